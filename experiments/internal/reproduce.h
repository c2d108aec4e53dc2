#pragma once
/// What `reproduce` (reproduce_command.cc) shares with its report (reproduce_report.cc).

#include <nlohmann/json.hpp>

#include <cstdint>
#include <filesystem>
#include <string>

namespace sonicboom::experiments {

/// The paper's 3-D MED per scenario (Table II), cm, in the order of kScenarios.
inline constexpr double kPaperMedCm[] = {0.43, 1.01, 2.01, 2.22};
inline constexpr const char* kScenarios[] = {"ts1", "ts2", "ts3", "ts4"};
/// Held-out strikes start at this sample index, which no training strike has.
inline constexpr int64_t kTestFirstIndex = 100000;
/// The lightweight model of the preprocessing ablation (the latency profile: compact encoder,
/// width 64, 2 blocks).
inline constexpr const char* kLightModelConfig = "study_fast.yaml";

/// The commit checked out at `root` (its .git/HEAD, a loose ref or packed-refs): the checkout a
/// run's commands came from, not necessarily the commit the binary was built from; "unknown"
/// outside a git checkout.
std::string CheckoutCommit(const std::filesystem::path& root);

/// DIR/report.md from results.json's content, for a run of `--size size`.
std::string ReproduceReport(const nlohmann::json& results, const std::string& size);

}  // namespace sonicboom::experiments
