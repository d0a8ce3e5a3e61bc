// Self-registering subcommands of the `shine` executable: each cli/cmd_*.cpp adds one.
#pragma once

#include <CLI/CLI.hpp>
#include <functional>
#include <string>
#include <vector>

namespace shine::cli {

/// The action a parsed subcommand runs; returns the process exit code.
using Action = std::function<int()>;

/// Adds a subcommand to `app`; when it is chosen its callback stores the work in `action`.
using CommandSetup = std::function<void(CLI::App& app, Action& action)>;

struct Command {
    int order;  ///< position in `shine --help`
    CommandSetup setup;
};

std::vector<Command>& command_registry();

/// A static instance of this in a cmd_*.cpp file registers the command.
struct RegisterCommand {
    RegisterCommand(int order, CommandSetup setup) {
        command_registry().push_back({order, std::move(setup)});
    }
};

}  // namespace shine::cli
