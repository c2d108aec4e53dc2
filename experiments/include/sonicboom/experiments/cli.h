#pragma once
/// The `sonicboom` command line: subcommands, global options, error reporting and exit codes.

namespace sonicboom::experiments {

/// Runs the CLI. Returns 0 on success, 1 for bad input (the message names the file, key or
/// value), 2 for a usage error, 3 for an internal failure.
int RunCli(int argc, char** argv);

}  // namespace sonicboom::experiments
