#include "sonicboom/experiments/cli.h"

#include <CLI/CLI.hpp>

#include <cstdio>
#include <iostream>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "sonicboom/core/errors.h"
#include "sonicboom/core/log.h"
#include "sonicboom/core/progress.h"
#include "sonicboom/experiments/commands.h"

namespace sonicboom::experiments {

int RunCli(int argc, char** argv) {
  CLI::App app{"SonicBoom: acoustic contact localization on a robot link, from simulated strikes "
               "to trained localizers", "sonicboom"};
  app.require_subcommand(1);
  app.fallthrough();
  app.set_version_flag("--version", SONICBOOM_VERSION);

  // global options, accepted before or after the subcommand
  GlobalOptions g;
  int verbose = 0;
  app.add_option("--config", g.sources.files, "YAML config file (repeatable, merged in order)");
  app.add_option("--set", g.sources.overrides, "override one key: dotted.key=value (repeatable)");
  app.add_option("--seed", g.sources.seed, "global seed (sample i uses seed and i)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--threads", g.threads, "worker threads (0 = all cores)")
      ->check(CLI::NonNegativeNumber);
  app.add_flag("-v,--verbose", verbose, "more log output (repeatable)");
  app.add_flag("-q,--quiet", g.quiet, "warnings and errors only, no progress");
  app.add_flag("--json", g.json, "machine-readable result on stdout (logs stay on stderr)");

  // subcommands and their options
  std::function<CommandResult()> run;
  std::string out, in, data, model, wav, proprio, boundary = "simply-supported", joints, path;
  int64_t count = -1, first_index = -1, shard = 0, num_shards = 1, index = 0, mode_count = 20;
  bool ideal = false;
  std::vector<std::string> shards;

  auto* demo = app.add_subcommand("demo", "generate a small dataset, train, evaluate on held-out "
                                          "strikes and print the result table");
  demo->add_option("--out", out, "run directory (default runs/demo-<UTC time>)");
  demo->callback([&] { run = [&] { return RunDemo(g, out); }; });

  auto* generate = app.add_subcommand("generate", "simulate strikes into an HDF5 dataset");
  generate->add_option("--out", out, "dataset file (.h5)")->required();
  generate->add_option("--count", count, "number of strikes (default dataset.count)");
  generate->add_option("--first-index", first_index, "global index of the first strike");
  generate->add_option("--shard", shard, "this shard (owns indices i with i % num-shards == shard)");
  generate->add_option("--num-shards", num_shards, "number of shards");
  generate->callback([&] {
    run = [&] { return RunGenerate(g, out, count, first_index, shard, num_shards); };
  });

  auto* merge = app.add_subcommand("merge", "join dataset shards into one file");
  merge->add_option("--out", out, "merged dataset file")->required();
  merge->add_option("shards", shards, "shard files")->required();
  merge->callback([&] { run = [&] { return RunMerge(g, out, shards); }; });

  auto* synth = app.add_subcommand("synth", "one strike as a 6-channel WAV plus a JSON label");
  synth->add_option("--out", out, "WAV file")->required();
  synth->add_option("--index", index, "sample index (with --seed it fixes the strike)");
  synth->callback([&] { run = [&] { return RunSynth(g, out, index); }; });

  auto* modes = app.add_subcommand("modes", "natural frequencies of the tube");
  modes->add_option("--boundary", boundary, "simply-supported | free");
  modes->add_flag("--ideal", ideal, "ideal uniform tube (no seam, no holes)");
  modes->add_option("--count", mode_count, "number of modes (pairs count twice)");
  modes->callback([&] { run = [&] { return RunModes(g, boundary, ideal, mode_count); }; });

  std::string fidelity_out = "docs/fidelity.md";
  int64_t fidelity_strikes = 4;
  double fidelity_window_s = 0.03;
  bool fidelity_quick = false;
  auto* fidelity = app.add_subcommand("fidelity", "time and error of every vibration-model rung "
                                                  "against the finest FD reference");
  fidelity->add_option("--out", fidelity_out, "markdown table (\"\" = print only)");
  fidelity->add_option("--strikes", fidelity_strikes, "test strikes (1-6)");
  fidelity->add_option("--window-s", fidelity_window_s, "compared signal after the onset, s");
  fidelity->add_flag("--quick", fidelity_quick, "coarse grids only (a smoke run)");
  fidelity->callback([&] {
    run = [&] { return RunFidelity(g, fidelity_out, fidelity_strikes, fidelity_window_s, fidelity_quick); };
  });

  int64_t variants_check = 3;
  std::string variants_out;
  auto* variants = app.add_subcommand("variants", "the structure pool's Ritz modes against full "
                                                  "solves: error and time");
  variants->add_option("--check", variants_check, "variants also solved in full (default 3)");
  variants->add_option("--out", variants_out, "markdown table (default: print only)");
  variants->callback([&] { run = [&] { return RunVariants(g, variants_check, variants_out); }; });

  auto* features = app.add_subcommand("features", "mel spectrograms and GCC-PHAT of a WAV or dataset");
  features->add_option("--in", in, "WAV file or dataset (.h5)")->required();
  features->add_option("--out", out, "features file (.h5)")->required();
  features->add_option("--proprio", proprio, "robot log CSV for a WAV input");
  features->callback([&] { run = [&] { return RunFeatures(g, in, out, proprio); }; });

  TrainOptions train_options;
  double train_lr = 0.0;
  int64_t train_epochs = 0;
  auto* train = app.add_subcommand("train", "train a localizer on a dataset, or fine-tune a "
                                            "pretrained one (--init-from)");
  train->add_option("--data", train_options.data, "training dataset (.h5)")->required();
  train->add_option("--out", train_options.out, "run directory")->required();
  train->add_flag("--resume", train_options.resume, "continue from the run directory's checkpoint");
  train->add_option("--init-from", train_options.init_from,
                    "pretrained run directory: start from its weights and config");
  train->add_option("--freeze", train_options.freeze,
                    "none | encoders | all-but-head (with --init-from)");
  train->add_option("--norm", train_options.norm,
                    "keep | refit the per-mic mel statistics (with --init-from; default keep)");
  train->add_option("--lr", train_lr, "learning rate (sets train.learning_rate)")
      ->check(CLI::PositiveNumber);
  train->add_option("--epochs", train_epochs, "epochs (sets train.epochs)")
      ->check(CLI::PositiveNumber);
  train->callback([&] {
    if (train_lr > 0.0) g.sources.overrides.push_back(fmt::format("train.learning_rate={}", train_lr));
    if (train_epochs > 0) g.sources.overrides.push_back(fmt::format("train.epochs={}", train_epochs));
    run = [&] { return RunTrain(g, train_options); };
  });

  auto* eval = app.add_subcommand("eval", "evaluate a trained localizer on a dataset");
  eval->add_option("--model", model, "run directory")->required();
  eval->add_option("--data", data, "dataset (.h5)")->required();
  eval->callback([&] { run = [&] { return RunEval(g, model, data); }; });

  BaselineOptions baseline_options;
  auto* baseline = app.add_subcommand("baseline", "a baseline's errors on a dataset: kNN on "
                                                  "pooled log-mel, analytic TDOA, or a constant");
  baseline->add_option("--method", baseline_options.method, "knn | tdoa | arrival | constant")->required();
  baseline->add_option("--train", baseline_options.train,
                       "training dataset (.h5): knn and constant need it; tdoa fits its speed "
                       "scale on it");
  baseline->add_option("--data", baseline_options.data, "held-out dataset (.h5)")->required();
  baseline->add_option("--k", baseline_options.k, "knn: neighbours")->check(CLI::PositiveNumber);
  baseline->add_option("--gcc-lags", baseline_options.knn_gcc_lags,
                       "knn: GCC-PHAT lags each side of zero in the feature vector (0 = none)")
      ->check(CLI::NonNegativeNumber);
  baseline->add_option("--bands", baseline_options.bands_hz,
                       "tdoa: band edges in Hz, e.g. 1000,2000,4000,8000,16000")
      ->delimiter(',');
  baseline->add_flag("--non-dispersive", baseline_options.non_dispersive,
                     "tdoa: one speed for every band");
  baseline->add_flag("--no-fit", baseline_options.no_fit, "tdoa: analytic speeds only");
  baseline->add_option("--fit-strikes", baseline_options.fit_strikes,
                       "tdoa: training strikes used by the speed fit")
      ->check(CLI::PositiveNumber);
  baseline->callback([&] { run = [&] { return RunBaseline(g, baseline_options); }; });

  AblateOptions ablate_options;
  auto* ablate = app.add_subcommand("ablate", "train and evaluate every ablation config (modality "
                                              "sets, preprocessing switches) and write a table");
  ablate->add_option("--data", ablate_options.data, "training dataset (.h5)")->required();
  ablate->add_option("--test", ablate_options.test, "held-out dataset (.h5)")->required();
  ablate->add_option("--out", ablate_options.out, "output directory")->required();
  ablate->add_option("--configs", ablate_options.configs_dir, "directory of ablation YAML layers");
  ablate->add_option("--only", ablate_options.only, "ablation names to run (default all)")
      ->delimiter(',');
  ablate->callback([&] { run = [&] { return RunAblate(g, ablate_options); }; });

  auto* localize = app.add_subcommand("localize", "locate the contact of one recorded strike");
  std::string localize_method = "network";
  localize->add_option("--method", localize_method,
                       "network (a trained run, --model) | arrival (no training: first arrivals)");
  localize->add_option("--model", model, "run directory (--method network)");
  localize->add_option("--wav", wav, "6-channel WAV")->required();
  localize->add_option("--proprio", proprio, "robot log CSV");
  int64_t localize_repeat = 1;
  localize->add_option("--repeat", localize_repeat,
                       "time the WAV-read-to-answer path this many times (median reported)");
  localize->callback([&] {
    run = [&] {
      if (localize_method == "arrival") {
        if (!model.empty()) throw ConfigError("localize --method arrival uses no --model");
        return RunLocalizeByArrival(g, wav);
      }
      if (localize_method != "network") {
        throw ConfigError(fmt::format("localize --method '{}' must be network or arrival",
                                      localize_method));
      }
      if (model.empty()) throw ConfigError("localize --method network needs --model RUN");
      return RunLocalize(g, model, wav, proprio, localize_repeat);
    };
  });

  ImportOptions import_options;
  auto* import = app.add_subcommand("import", "recorded strikes (published trial layout or our "
                                              "capture layout) into a dataset");
  import->add_option("--layout", import_options.layout, "trial | capture")->required();
  import->add_option("--in", import_options.in, "capture directory")->required();
  import->add_option("--out", import_options.out, "dataset file (.h5)")->required();
  import->add_option("--angle-convention", import_options.angle_convention,
                     "tube (docs/conventions.md) | j7 (published joint-7 angle)");
  import->add_option("--min-duration-s", import_options.min_duration_s,
                     "shorter captures are bad (default 1.5)");
  import->add_option("--object", import_options.object,
                     "label trials from geometry: the object (ply, obj, stl, pts, xyz, robot base "
                     "frame) met by the tube placed from each trial's q_t.npy");
  import->add_option("--object-scale", import_options.object_scale,
                     "object units to metres (0.001 for millimetres)");
  import->add_option("--contact-tolerance-m", import_options.contact_tolerance_m,
                     "contact when the object comes this close (default 0.002)");
  import->add_flag("--skip-bad", import_options.skip_bad,
                   "import the good captures when some are bad (they are listed)");
  import->add_flag("--force", import_options.force, "replace an existing output");
  import->callback([&] { run = [&] { return RunImport(g, import_options); }; });

  std::string export_layout = "trial", angle_convention = "tube";
  auto* export_cmd = app.add_subcommand("export", "a dataset in the published trial layout");
  export_cmd->add_option("--layout", export_layout, "trial");
  export_cmd->add_option("--in", in, "dataset (.h5)")->required();
  export_cmd->add_option("--out", out, "new directory")->required();
  export_cmd->add_option("--angle-convention", angle_convention, "tube | j7");
  export_cmd->callback([&] {
    run = [&] { return RunExport(g, export_layout, in, out, angle_convention); };
  });

  ListenOptions listen_options;
  auto* listen = app.add_subcommand("listen", "live localization: strikes from a sound device (or "
                                              "a WAV read as one), one JSON line each");
  listen->add_option("--model", listen_options.model, "run directory")->required();
  listen->add_option("--device", listen_options.device,
                     "input device, part of its name (ALSA, e.g. hw:1,0); default input if empty");
  listen->add_option("--wav", listen_options.wav, "read this WAV as the device stream");
  listen->add_flag("--realtime", listen_options.realtime, "pace the WAV at its sample rate");
  listen->add_option("--save", listen_options.save, "session directory (capture layout)");
  listen->add_option("--max-events", listen_options.max_events, "stop after N strikes (0: never)");
  listen->add_option("--threshold-db", listen_options.threshold_db,
                     "onset threshold above the noise floor (default 20)");
  listen->callback([&] { run = [&] { return RunListen(g, listen_options); }; });

  int64_t check_count = 100;
  std::string check_out, check_scenes;
  auto* geometry_check = app.add_subcommand(
      "geometry-check", "labels from geometry against the simulator's labels on MuJoCo strikes");
  geometry_check->add_option("--count", check_count, "strikes (default 100)");
  geometry_check->add_option("--out", check_out, "write the result line to this file");
  geometry_check->add_option("--scenes", check_scenes,
                             "keep each strike's exported scene here (object.ply, q_t.npy); "
                             "default: a temporary directory, removed");
  geometry_check->callback(
      [&] { run = [&] { return RunGeometryCheck(g, check_count, check_out, check_scenes); }; });

  auto* fk = app.add_subcommand("fk", "flange and tube poses of the Panda for joint angles");
  fk->add_option("--joints", joints, "q1,...,q7 in rad")->required();
  fk->callback([&] { run = [&] { return RunFk(g, joints); }; });

  auto* inspect = app.add_subcommand("inspect", "summarize a file or run directory SonicBoom wrote");
  inspect->add_option("path", path, "dataset, features file, WAV, run directory or config")
      ->required();
  inspect->callback([&] { run = [&] { return RunInspect(g, path); }; });

  std::string markdown_sections;
  auto* config = app.add_subcommand("config", "print the resolved config");
  config->add_option("--markdown", markdown_sections,
                     "SECTIONS: a Markdown table of the keys of these comma-separated sections "
                     "(docs/conventions.md)");
  config->callback([&] { run = [&] { return RunConfig(g, markdown_sections); }; });

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
  try {
    const CommandResult result = run();
    std::cout << (g.json ? result.json + "\n" : result.text);
    std::cout.flush();
    return 0;
  } catch (const Error& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "internal error: %s\n", e.what());
    return 3;
  }
}

}  // namespace sonicboom::experiments
