// Error types of ShineVDB.
//
// Every failure that a user can cause (a missing file, a malformed value, an impossible
// configuration) is reported as a shine::Error whose message names the file or key, the value
// and, where there is one, the fix. Only the CLI's main() turns an Error into an exit code.
#pragma once

#include <stdexcept>
#include <string>

namespace shine {

/// Base of all errors ShineVDB reports to users.
class Error : public std::runtime_error {
  public:
    explicit Error(const std::string& message) : std::runtime_error(message) {}
};

/// A file could not be opened, read, parsed or written: the message names the file and the place.
class IoError : public Error {
  public:
    using Error::Error;
};

/// A configuration key or command-line value is unknown or out of range.
class ConfigError : public Error {
  public:
    using Error::Error;
};

/// Input data is valid on its own but inconsistent (e.g. fewer poses than scans).
class DataError : public Error {
  public:
    using Error::Error;
};

/// A run was asked to stop (SIGINT/SIGTERM) and stopped cleanly.
class Interrupted : public Error {
  public:
    using Error::Error;
};

}  // namespace shine
