// The `shine` command: a thin layer over the library; subcommands live in cmd_*.cpp.
#include <algorithm>
#include <cstdio>
#include <exception>

#include "command_registry.hpp"
#include "shine/core/error.hpp"

namespace shine::cli {
std::vector<Command>& command_registry() {
    static std::vector<Command> registry;
    return registry;
}
}  // namespace shine::cli

int main(int argc, char** argv) {
    using namespace shine::cli;
    CLI::App app{
        "ShineVDB: LiDAR scans with known poses -> sparse hierarchical neural SDF map (OpenVDB) "
        "-> level set and mesh"};
    app.require_subcommand(1);
    app.set_version_flag("--version", "shine 0.1.0");
    Action action;
    auto& commands = command_registry();
    std::stable_sort(commands.begin(), commands.end(),
                     [](const Command& a, const Command& b) { return a.order < b.order; });
    for (const auto& command : commands) command.setup(app, action);
    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
        return app.exit(e);
    }
    if (!action) return 0;
    try {
        return action();
    } catch (const shine::Interrupted& e) {
        std::fprintf(stderr, "shine: interrupted: %s\n", e.what());
        return 130;
    } catch (const shine::Error& e) {
        std::fprintf(stderr, "shine: error: %s\n", e.what());
        return 1;
    } catch (const std::bad_alloc&) {
        std::fprintf(stderr, "shine: error: out of memory\n");
        return 1;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "shine: internal error: %s\n", e.what());
        return 2;
    }
}
