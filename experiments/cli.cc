#include "sonicboom/experiments/cli.h"

#include <CLI/CLI.hpp>

#include <cstdio>
#include <iostream>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "internal/subcommands.h"
#include "sonicboom/core/cache_dir.h"
#include "sonicboom/core/cache_use.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/core/log.h"
#include "sonicboom/core/progress.h"
#include "sonicboom/experiments/commands.h"

namespace sonicboom::experiments {

int RunCli(int argc, char** argv) {
  CLI::App app{
      "SonicBoom: acoustic contact localization on a robot link, from simulated strikes "
      "to trained localizers",
      "sonicboom"};
  app.require_subcommand(1);
  app.fallthrough();
  app.set_version_flag("--version", SONICBOOM_VERSION);

  // global options, accepted before or after the subcommand
  GlobalOptions g;
  int verbose = 0;
  app.add_option("--config", g.sources.files, "YAML config file (repeatable, merged in order)");
  app.add_option("--set", g.sources.overrides, "override one key: dotted.key=value (repeatable)");
  app.add_option("--seed", g.sources.seed, "global seed (sample i uses seed and i)")
      ->check(NumberIn(0, 9.2e18, false, true));
  app.add_option("--threads", g.threads, "worker threads (0 = all cores)")
      ->check(NumberIn(0, 4096, false, true));
  app.add_flag("-v,--verbose", verbose, "more log output (repeatable)");
  app.add_flag("-q,--quiet", g.quiet, "warnings and errors only, no progress");
  app.add_flag("--json", g.json, "machine-readable result on stdout (logs stay on stderr)");

  // subcommands, each registered beside its Run function (internal/subcommands.h)
  Runner run;
  for (auto* register_subcommand :
       {RegisterDemo,      RegisterGenerate, RegisterMerge,     RegisterSynth,
        RegisterModes,     RegisterExact,    RegisterFidelity, RegisterReference, RegisterRerender,
        RegisterVariants,  RegisterFeatures, RegisterTrain,     RegisterPretrain,
        RegisterEval,
        RegisterCalibrate, RegisterBaseline, RegisterAblate,    RegisterLocalize,
        RegisterImport,    RegisterExport,   RegisterListen,    RegisterGeometryCheck,
        RegisterMap,       RegisterFk,       RegisterInspect,   RegisterConfig,
        RegisterAdapt,     RegisterReproduce, RegisterCache}) {
    register_subcommand(app, g, &run);
  }

  // parse; usage errors exit 2 with CLI11's message
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    app.exit(e);
    return 2;
  }

  // --threads also bounds training's intra-op threads, visible in the resolved config
  if (g.threads > 0) g.sources.overrides.push_back(fmt::format("train.threads={}", g.threads));

  // run; bad input exits 1 with a message naming the culprit
  SetUpLogging(g.quiet ? -1 : verbose);
  Progress::SetQuiet(g.quiet);
  // the command's working set in the mode cache stays while it runs; its end prunes to the budget
  internal::SpareThisProcessesCacheEntries();
  struct PruneAtEnd {
    ~PruneAtEnd() { internal::PruneSparedCachesToBudget(); }
  } prune_at_end;
  try {
    internal::CacheBudgetBytes();  // a bad SONICBOOM_CACHE_MAX_BYTES is refused before any work
    const CommandResult result = run();
    std::cout << (g.json ? result.json + "\n" : result.text);
    std::cout.flush();
    return 0;
  } catch (const Error& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  } catch (const std::filesystem::filesystem_error& e) {
    // the file system refused a path the user gave (permissions, a name too long, a link loop)
    // (one without a path, e.g. a temporary directory the environment names, says its operation)
    if (e.path1().empty()) {
      std::fprintf(stderr, "error: %s\n", e.what());
    } else {
      std::fprintf(stderr, "error: %s: %s\n", e.path1().c_str(), e.code().message().c_str());
    }
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "internal error: %s\n", e.what());
    return 3;
  }
}

}  // namespace sonicboom::experiments
