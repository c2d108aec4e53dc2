#pragma once
/// Logging set-up. Call sites include <spdlog/spdlog.h> in .cc files only.

namespace sonicboom {

/// verbosity: -1 quiet (warnings and errors), 0 info, 1 debug, 2 trace. Logs go to stderr.
void SetUpLogging(int verbosity);

}  // namespace sonicboom
