// `fk`: flange and tube poses of the Panda for joint angles.
#include "sonicboom/experiments/commands.h"

#include <CLI/CLI.hpp>

#include <cmath>
#include <sstream>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "sonicboom/core/errors.h"
#include "sonicboom/sim/franka.h"

#include "internal/report.h"
#include "internal/subcommands.h"

namespace sonicboom::experiments {

using nlohmann::json;

CommandResult RunFk(const GlobalOptions& g, const std::string& joints) {
  const SonicBoomConfig config = Resolve(g);
  // seven comma-separated angles inside the joint limits
  std::vector<double> q_list;
  std::stringstream ss(joints);
  for (std::string cell; std::getline(ss, cell, ',');) {
    try {
      size_t used = 0;
      q_list.push_back(std::stod(cell, &used));
      if (used != cell.size()) throw std::invalid_argument(cell);
    } catch (const std::exception&) {
      throw ConfigError(fmt::format("--joints: '{}' is not a number", cell));
    }
  }
  if (q_list.size() != sim::kPandaJoints) {
    throw ConfigError(
        fmt::format("--joints needs {} values, got {}", sim::kPandaJoints, q_list.size()));
  }
  sim::JointVector q;
  const sim::JointVector lo = sim::PandaLowerLimits(), hi = sim::PandaUpperLimits();
  for (int i = 0; i < sim::kPandaJoints; ++i) {
    q[i] = q_list[i];
    if (!std::isfinite(q[i]) || q[i] < lo[i] || q[i] > hi[i]) {
      throw ConfigError(fmt::format("--joints: joint {} = {} rad is outside its limits [{}, {}]",
                                    i + 1, q[i], lo[i], hi[i]));
    }
  }
  const sim::PandaPoses poses = sim::PandaForwardKinematics(q, config.tube.center_from_flange_m);
  auto quat = [](const Eigen::Isometry3d& t) {
    const Eigen::Quaterniond qt(t.linear());
    return std::vector<double>{qt.w(), qt.x(), qt.y(), qt.z()};
  };
  auto pos = [](const Eigen::Isometry3d& t) {
    return std::vector<double>{t.translation().x(), t.translation().y(), t.translation().z()};
  };
  json j = {{"flange_pos_m", pos(poses.flange)},
            {"flange_quat_wxyz", quat(poses.flange)},
            {"tube_center_pos_m", pos(poses.tube)},
            {"tube_quat_wxyz", quat(poses.tube)}};
  const auto fp = pos(poses.flange), tp = pos(poses.tube);
  return {j.dump(), fmt::format("flange at ({:.4f}, {:.4f}, {:.4f}) m, tube centre at ({:.4f}, "
                                "{:.4f}, {:.4f}) m (robot base frame)\n",
                                fp[0], fp[1], fp[2], tp[0], tp[1], tp[2])};
}

void RegisterFk(CLI::App& app, GlobalOptions& g, Runner* run) {
  auto joints = std::make_shared<std::string>();
  auto* fk = app.add_subcommand("fk", "flange and tube poses of the Panda for joint angles");
  fk->add_option("--joints", *joints, "q1,...,q7 in rad")->required();
  fk->callback([&g, run, joints] { *run = [&g, joints] { return RunFk(g, *joints); }; });
}

}  // namespace sonicboom::experiments
