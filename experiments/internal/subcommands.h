#pragma once
/// Each subcommand's registration lives beside its Run function (experiments/*_command.cc and the
/// study files): it declares the subcommand and its options on `app`, and when the subcommand is
/// chosen, sets `*run`. Option values live in state the callbacks share, so they outlive parsing.
/// Private to experiments; cli.cc calls them in the order `--help` lists them.

#include <CLI/CLI.hpp>

#include <cmath>
#include <cstdlib>
#include <functional>
#include <optional>
#include <string>

#include "sonicboom/core/archive.h"
#include "sonicboom/experiments/commands.h"

namespace sonicboom::experiments {

using Runner = std::function<CommandResult()>;

/// An option whose value is one of an enum's names (EnumNames); any other value is a usage error
/// (exit 2) naming the option and the names it takes.
template <typename E>
CLI::Option* AddEnumOption(CLI::App* app, const std::string& name, E* value,
                           const std::string& help) {
  const std::string names = EnumNameList<E>();
  return app->add_option_function<std::string>(
      name,
      [name, names, value](const std::string& given) {
        const std::optional<E> e = EnumFromName<E>(given);
        if (!e) throw CLI::ValidationError(name, "'" + given + "' is not one of: " + names);
        *value = *e;
      },
      help);
}

/// A numeric option's check: a plain finite number in [lo, hi] ((lo, hi] when lo_open), a whole
/// one when `whole`; its message says so in words (CLI11's range checks print the largest double
/// in 309 digits and let NaN through).
inline CLI::Validator NumberIn(double lo, double hi, bool lo_open = false, bool whole = false) {
  const std::string range = (lo_open ? "(" : "[") + CLI::detail::to_string(lo) + ", " +
                            CLI::detail::to_string(hi) + "]";
  const std::string kind = whole ? "a whole number" : "a number";
  return CLI::Validator(
      [=](std::string& text) -> std::string {
        char* end = nullptr;
        const double v = std::strtod(text.c_str(), &end);
        const bool parsed = !text.empty() && end == text.c_str() + text.size() && std::isfinite(v);
        const bool inside = parsed && (lo_open ? v > lo : v >= lo) && v <= hi &&
                            (!whole || v == std::floor(v));
        return inside ? std::string() : "'" + text + "' is not " + kind + " in " + range;
      },
      kind + " in " + range);
}

void RegisterDemo(CLI::App& app, GlobalOptions& g, Runner* run);
void RegisterGenerate(CLI::App& app, GlobalOptions& g, Runner* run);
void RegisterMerge(CLI::App& app, GlobalOptions& g, Runner* run);
void RegisterSynth(CLI::App& app, GlobalOptions& g, Runner* run);
void RegisterModes(CLI::App& app, GlobalOptions& g, Runner* run);
void RegisterExact(CLI::App& app, GlobalOptions& g, Runner* run);
void RegisterFidelity(CLI::App& app, GlobalOptions& g, Runner* run);
void RegisterReference(CLI::App& app, GlobalOptions& g, Runner* run);
void RegisterRerender(CLI::App& app, GlobalOptions& g, Runner* run);
void RegisterVariants(CLI::App& app, GlobalOptions& g, Runner* run);
void RegisterFeatures(CLI::App& app, GlobalOptions& g, Runner* run);
void RegisterTrain(CLI::App& app, GlobalOptions& g, Runner* run);
void RegisterPretrain(CLI::App& app, GlobalOptions& g, Runner* run);
void RegisterEval(CLI::App& app, GlobalOptions& g, Runner* run);
void RegisterCalibrate(CLI::App& app, GlobalOptions& g, Runner* run);
void RegisterAdapt(CLI::App& app, GlobalOptions& g, Runner* run);
void RegisterReproduce(CLI::App& app, GlobalOptions& g, Runner* run);
void RegisterBaseline(CLI::App& app, GlobalOptions& g, Runner* run);
void RegisterAblate(CLI::App& app, GlobalOptions& g, Runner* run);
void RegisterLocalize(CLI::App& app, GlobalOptions& g, Runner* run);
void RegisterImport(CLI::App& app, GlobalOptions& g, Runner* run);
void RegisterExport(CLI::App& app, GlobalOptions& g, Runner* run);
void RegisterListen(CLI::App& app, GlobalOptions& g, Runner* run);
void RegisterGeometryCheck(CLI::App& app, GlobalOptions& g, Runner* run);
void RegisterFk(CLI::App& app, GlobalOptions& g, Runner* run);
void RegisterInspect(CLI::App& app, GlobalOptions& g, Runner* run);
void RegisterMap(CLI::App& app, GlobalOptions& g, Runner* run);
void RegisterConfig(CLI::App& app, GlobalOptions& g, Runner* run);
void RegisterCache(CLI::App& app, GlobalOptions& g, Runner* run);

}  // namespace sonicboom::experiments
