#pragma once
/// Error types. Exceptions are for bad user input at boundaries (files, config, CLI);
/// SONICBOOM_DEMAND is for broken internal invariants and aborts.

#include <stdexcept>
#include <string>

namespace sonicboom {

/// Base of every error the CLI reports as "error: <message>" with a non-zero exit.
class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};
/// A config key is unknown, mistyped or out of range. The message names the key and its source.
class ConfigError : public Error {
 public:
  using Error::Error;
};
/// A file is missing, unreadable, truncated or of the wrong shape. The message names the file.
class IoError : public Error {
 public:
  using Error::Error;
};
/// A file was written by something else, an incompatible schema version, or is incomplete.
class SchemaError : public Error {
 public:
  using Error::Error;
};
/// A numerical setting cannot work (unstable, non-finite result). The message names the limit.
class NumericalError : public Error {
 public:
  using Error::Error;
};

namespace internal {
[[noreturn]] void AbortOnFailedDemand(const char* condition, const char* file, int line);
}  // namespace internal

}  // namespace sonicboom

/// Invariant check, armed in every build type.
#define SONICBOOM_DEMAND(cond)                                                          \
  do {                                                                                  \
    if (!(cond)) ::sonicboom::internal::AbortOnFailedDemand(#cond, __FILE__, __LINE__); \
  } while (0)
