#pragma once
/// The step loop every dynamic strike shares (the arm's rollout, the hand-held striker) and the
/// contact-episode bookkeeping in it: touch, release, kinds, forces, the settle time after the
/// first hard contact. Private to the sim module (includes mujoco.h).

#include <mujoco/mujoco.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <algorithm>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "sonicboom/core/sample.h"
#include "sonicboom/core/tube.h"
#include "sonicboom/sim/rollout_result.h"

namespace sonicboom::sim::internal {

/// Marks `result` invalid for `reason`, keeping the first reason given.
void Fail(RolloutResult* result, std::string reason);

/// The deepest of d's contacts listed in `contacts` (indices into d->contact; not empty).
const mjContact& DeepestContact(const mjData* d, const std::vector<int>& contacts);

/// A tube contact record at touch from MuJoCo contact `c`: time, raw point (world and tube
/// frame), outward (tube to object) normal in the tube frame, z and theta from the raw point.
/// `tube_pose`: tube frame in the world; `normal_world` receives the outward normal, world.
ContactRecord TouchRecord(const mjContact& c, int tube_geom, const Eigen::Isometry3d& tube_pose,
                          double t_s, Eigen::Vector3d* normal_world);

/// Why a touch is not a trustworthy contact, or "": a raw point more than 1 mm off the tube
/// surface, or a first contact outside the contact region (never clamped).
std::string TouchProblem(const ContactRecord& rec, const TubeConfig& tube, bool first);

/// Adds one step's normal force (N) of d's listed contacts to rec's impulse and peak force.
void AccumulateForce(const mjModel* m, const mjData* d, const std::vector<int>& contacts,
                     double dt_s, ContactRecord* rec);

/// Kinds of a simulation's contact episodes, decided at release: the first hard contact is the
/// impact; a later one lasting longer than 20 ms a press; one that touched within 50 ms of the
/// previous release a bounce; any other an impact.
class EpisodeClassifier {
 public:
  /// Time since the previous release, for an episode touching at touch_s (s; huge if none).
  double SinceRelease(double touch_s) const {
    return any_release_ ? touch_s - last_release_s_ : 1e9;
  }
  /// Kind of an episode released at release_s, and the release noted.
  ContactEpisode::Kind Release(double since_release_s, double duration_s, bool first_hard,
                               double release_s) {
    any_release_ = true;
    last_release_s_ = release_s;
    if (first_hard) return ContactEpisode::Kind::kImpact;
    if (duration_s > kPressDurationS) return ContactEpisode::Kind::kPress;
    if (since_release_s <= kBounceWindowS) return ContactEpisode::Kind::kBounce;
    return ContactEpisode::Kind::kImpact;
  }

  static constexpr double kPressDurationS = 0.02;
  static constexpr double kBounceWindowS = 0.05;

 private:
  bool any_release_{false};
  double last_release_s_{0.0};
};

/// The tube's contact episodes of one simulation, written into a RolloutResult. A channel is one
/// thing the tube can touch: an object segment or a striker (hard: MuJoCo contacts, forces) or a
/// leaf cluster (soft: a brush, no force). At most one episode per channel is open at a time.
/// The simulation ends at end_s(): the record's end, or earlier where set_end_s says so, or
/// settle_s after the first hard touch (never after the record).
class EpisodeTracker {
 public:
  EpisodeTracker(RolloutResult* result, const TubeConfig& tube, double record_s, double settle_s);
  void set_end_s(double end_s) { end_s_ = std::min(record_s_, end_s); }

  /// A hard channel: its episode closes once its contacts stay away `release_steps` steps, at the
  /// first of them. Returns the channel's id (channels are numbered in the order added).
  int AddHardChannel(int64_t release_steps);
  /// A soft channel: its episode (a brush) closes at the first step without touch.
  int AddSoftChannel();

  /// This step's MuJoCo contacts of hard channel `ch` (indices into d->contact); filled by the
  /// caller after ClearContacts.
  std::vector<int>& contacts(int ch) { return channels_[static_cast<size_t>(ch)].contacts; }
  void ClearContacts();

  /// Hard channel `ch` at t_s, from its contacts: where its first contact appears, `touch` makes
  /// the episode's record from the deepest one (called only then); an untrustworthy touch
  /// (TouchProblem) fails the result.
  void ObserveHard(int ch, double t_s, const mjData* d,
                   const std::function<ContactRecord(const mjContact&)>& touch);
  /// Soft channel `ch` at t_s: touching or not; `touch` makes a new brush's record.
  void ObserveSoft(int ch, bool touching, double t_s, const std::function<ContactRecord()>& touch);
  /// Adds the normal force of this step's contacts (solved by mj_step2) to every open hard
  /// episode, over span_s.
  void AccumulateForces(const mjModel* m, const mjData* d, double span_s);
  /// Closes every open episode at t_s, channels in the order added.
  void CloseAll(double t_s);

  double end_s() const { return end_s_; }
  int first_hard() const { return first_hard_; }           // index into the contacts; -1: none yet
  double last_change_s() const { return last_change_s_; }  // an episode last opened or closed

 private:
  struct Channel {
    bool hard{true};
    int64_t release_steps{1};
    int open{-1};                 // index into result->contacts; -1: none open
    int64_t missing_steps{0};     // steps without contact while open
    double missing_since_s{0.0};  // the first of them, s
    std::vector<int> contacts;    // this step's MuJoCo contacts (hard channels)
  };
  int Open(ContactRecord rec);
  void Close(Channel* channel, double t_s);

  RolloutResult* result_;
  const TubeConfig& tube_;
  double end_s_, record_s_, settle_s_;
  std::vector<Channel> channels_;
  std::vector<double> since_release_s_;  // per contact: time since the last release at touch
  int first_hard_{-1};
  double last_change_s_{-1.0};
  EpisodeClassifier kinds_;
};

/// One step's choice: the model to step (a twin of the full model with fewer collision pairs, or
/// a larger timestep) and how many timesteps it spans.
struct StepChoice {
  const mjModel* model{nullptr};
  int64_t advance{1};
};

/// The shared step loop. From first_step * dt_s on the audio clock until the tracker's end:
/// choose a model, mj_step1 (kinematics and collisions at t), observe (rows, contacts, episodes,
/// control; may fail the result), mj_step2, then the forces of the step. A MuJoCo warning or a
/// non-finite state fails the result. Ends with every episode closed; sets result->steps and
/// result->simulated_s. `model` is the full model (forces are read with it).
struct StepLoop {
  const mjModel* model{nullptr};
  mjData* data{nullptr};
  double dt_s{0.0};
  int64_t first_step{0};
  std::function<StepChoice(double t_s, int64_t step)> choose;
  std::function<void(double t_s, int64_t step)> observe;
};
void RunSteps(const StepLoop& loop, EpisodeTracker* tracker, RolloutResult* result);

}  // namespace sonicboom::sim::internal
