#include "internal/episodes.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <utility>

#include "internal/mujoco_util.h"
#include "sonicboom/core/errors.h"

namespace sonicboom::sim::internal {

void Fail(RolloutResult* result, std::string reason) {
  if (!result->valid) return;  // keep the first reason
  result->valid = false;
  result->invalid_reason = std::move(reason);
}

const mjContact& DeepestContact(const mjData* d, const std::vector<int>& contacts) {
  SONICBOOM_DEMAND(!contacts.empty());
  int deepest = contacts.front();
  for (int i : contacts) {
    if (d->contact[i].dist < d->contact[deepest].dist) deepest = i;
  }
  return d->contact[deepest];
}

ContactRecord TouchRecord(const mjContact& c, int tube_geom, const Eigen::Isometry3d& tube_pose,
                          double t_s, Eigen::Vector3d* normal_world_out) {
  // outward normal: MuJoCo's normal points from geom1 to geom2
  Eigen::Vector3d normal_world(c.frame[0], c.frame[1], c.frame[2]);
  if (c.geom1 != tube_geom) normal_world = -normal_world;
  *normal_world_out = normal_world;
  ContactRecord rec;
  rec.time_s = t_s;
  rec.point_world_m = Eigen::Vector3d(c.pos[0], c.pos[1], c.pos[2]);
  rec.point_m = tube_pose.inverse() * rec.point_world_m;
  rec.normal = tube_pose.linear().transpose() * normal_world;
  rec.z_m = rec.point_m.z();
  rec.theta_rad = WrapAngle(std::atan2(rec.point_m.y(), rec.point_m.x()));
  return rec;
}

std::string TouchProblem(const ContactRecord& rec, const TubeConfig& tube, bool first) {
  constexpr double kSurfaceToleranceM = 0.001;  // largest |r - R_outer| of a raw contact point
  const double off_surface_m =
      std::abs(std::hypot(rec.point_m.x(), rec.point_m.y()) - tube.outer_radius_m);
  if (off_surface_m >= kSurfaceToleranceM) {
    return fmt::format("contact point off the tube surface by {:.3f} mm at t = {:.4f} s",
                       1e3 * off_surface_m, rec.time_s);
  }
  if (first && (rec.z_m < tube.contact_z_min_m || rec.z_m > tube.contact_z_max_m)) {
    return fmt::format("first contact at z = {:.4f} m outside the contact region [{}, {}] m",
                       rec.z_m, tube.contact_z_min_m, tube.contact_z_max_m);
  }
  return "";
}

void AccumulateForce(const mjModel* m, const mjData* d, const std::vector<int>& contacts,
                     double dt_s, ContactRecord* rec) {
  double normal_force_n = 0.0;
  for (int i : contacts) {
    mjtNum force[6];
    mj_contactForce(m, d, i, force);
    normal_force_n += force[0];
  }
  rec->impulse_Ns += normal_force_n * dt_s;
  rec->peak_force_N = std::max(rec->peak_force_N, normal_force_n);
}

EpisodeTracker::EpisodeTracker(RolloutResult* result, const TubeConfig& tube, double record_s,
                               double settle_s)
    : result_(result), tube_(tube), end_s_(record_s), record_s_(record_s), settle_s_(settle_s) {}

int EpisodeTracker::AddHardChannel(int64_t release_steps) {
  SONICBOOM_DEMAND(release_steps >= 1);
  Channel c;
  c.release_steps = release_steps;
  channels_.push_back(std::move(c));
  return static_cast<int>(channels_.size()) - 1;
}

int EpisodeTracker::AddSoftChannel() {
  Channel c;
  c.hard = false;
  channels_.push_back(std::move(c));
  return static_cast<int>(channels_.size()) - 1;
}

void EpisodeTracker::ClearContacts() {
  for (Channel& c : channels_) c.contacts.clear();
}

int EpisodeTracker::Open(ContactRecord rec) {
  last_change_s_ = rec.time_s;
  since_release_s_.push_back(kinds_.SinceRelease(rec.time_s));
  result_->contacts.push_back(std::move(rec));
  return static_cast<int>(result_->contacts.size()) - 1;
}

void EpisodeTracker::Close(Channel* channel, double t_s) {
  const int index = channel->open;
  channel->open = -1;
  last_change_s_ = t_s;
  ContactRecord& rec = result_->contacts[static_cast<size_t>(index)];
  rec.duration_s = t_s - rec.time_s;
  if (rec.kind == ContactEpisode::Kind::kBrush) return;
  rec.kind = kinds_.Release(since_release_s_[static_cast<size_t>(index)], rec.duration_s,
                            index == first_hard_, t_s);
}

void EpisodeTracker::ObserveHard(int ch, double t_s, const mjData* d,
                                 const std::function<ContactRecord(const mjContact&)>& touch) {
  Channel& c = channels_[static_cast<size_t>(ch)];
  SONICBOOM_DEMAND(c.hard);
  if (c.contacts.empty()) {
    // released once the contact has stayed away release_steps steps, at its first missing step
    if (c.open >= 0 && ++c.missing_steps == 1) c.missing_since_s = t_s;
    if (c.open >= 0 && c.missing_steps >= c.release_steps) Close(&c, c.missing_since_s);
    return;
  }
  c.missing_steps = 0;
  if (c.open >= 0) return;
  // a touch: the record from the deepest contact; the first hard one sets the end
  const ContactRecord rec = touch(DeepestContact(d, c.contacts));
  const bool first = first_hard_ < 0;
  const std::string problem = TouchProblem(rec, tube_, first);
  c.open = Open(rec);
  if (first) first_hard_ = c.open;
  if (!problem.empty()) Fail(result_, problem);
  if (first) end_s_ = std::min(record_s_, t_s + settle_s_);
}

void EpisodeTracker::ObserveSoft(int ch, bool touching, double t_s,
                                 const std::function<ContactRecord()>& touch) {
  Channel& c = channels_[static_cast<size_t>(ch)];
  SONICBOOM_DEMAND(!c.hard);
  if (!touching) {
    if (c.open >= 0) Close(&c, t_s);
    return;
  }
  if (c.open >= 0) return;
  ContactRecord rec = touch();
  rec.kind = ContactEpisode::Kind::kBrush;
  c.open = Open(std::move(rec));
}

void EpisodeTracker::AccumulateForces(const mjModel* m, const mjData* d, double span_s) {
  for (const Channel& c : channels_) {
    if (!c.hard || c.open < 0) continue;
    AccumulateForce(m, d, c.contacts, span_s, &result_->contacts[static_cast<size_t>(c.open)]);
  }
}

void EpisodeTracker::CloseAll(double t_s) {
  for (Channel& c : channels_) {
    if (c.open >= 0) Close(&c, t_s);
  }
}

void RunSteps(const StepLoop& loop, EpisodeTracker* tracker, RolloutResult* result) {
  mjData* d = loop.data;
  const double dt_s = loop.dt_s;
  int64_t step = 0;  // MuJoCo steps taken
  int64_t grid = 0;  // timesteps simulated (a step may span several)
  while (result->valid) {
    const double t_s = static_cast<double>(loop.first_step + grid) * dt_s;
    if (t_s >= tracker->end_s() - 0.5 * dt_s) break;
    const StepChoice choice = loop.choose(t_s, step);

    // positions and velocities at t: kinematics, collisions, mass matrix, bias forces
    mj_step1(choice.model, d);
    if (const char* warning = RaisedWarning(d)) {
      Fail(result, fmt::format("MuJoCo warning {} at t = {:.4f} s", warning, t_s));
      break;
    }
    // rows, contacts and episodes at t, and the control of the step
    tracker->ClearContacts();
    loop.observe(t_s, step);
    if (!result->valid) break;

    // actuation, constraint forces, integration to the next step
    mj_step2(choice.model, d);
    ++step;
    grid += choice.advance;
    if (const char* warning = RaisedWarning(d)) {
      Fail(result, fmt::format("MuJoCo warning {} at t = {:.4f} s", warning, t_s));
      break;
    }
    if (!AllFinite(d->qpos, loop.model->nq) || !AllFinite(d->qvel, loop.model->nv)) {
      Fail(result, fmt::format("non-finite state at t = {:.4f} s", t_s + dt_s));
      break;
    }
    // the normal force of this step's contacts (solved in mj_step2)
    tracker->AccumulateForces(loop.model, d, static_cast<double>(choice.advance) * dt_s);
  }
  tracker->CloseAll(static_cast<double>(loop.first_step + grid) * dt_s);
  result->steps = step;
  result->simulated_s = static_cast<double>(grid) * dt_s;
}

}  // namespace sonicboom::sim::internal
