#include "sonicboom/core/log.h"

#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

namespace sonicboom {

void SetUpLogging(int verbosity) {
  // one stderr logger, so --json output on stdout stays machine-readable
  auto logger = spdlog::stderr_color_mt("sonicboom");
  spdlog::set_default_logger(logger);
  spdlog::set_pattern("[%H:%M:%S] %^%l%$ %v");
  if (verbosity < 0) {
    spdlog::set_level(spdlog::level::warn);
  } else if (verbosity == 0) {
    spdlog::set_level(spdlog::level::info);
  } else if (verbosity == 1) {
    spdlog::set_level(spdlog::level::debug);
  } else {
    spdlog::set_level(spdlog::level::trace);
  }
}

}  // namespace sonicboom
