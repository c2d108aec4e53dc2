#include "sonicboom/core/constants.h"
#include "sonicboom/sim/franka_mjcf.h"

#include <fmt/format.h>

#include <array>
#include <cmath>
#include <numbers>
#include <string>
#include <vector>

#include "sonicboom/core/errors.h"
#include "sonicboom/sim/franka.h"

namespace sonicboom::sim {
namespace {

constexpr double kGravityMS2 = 9.81;

// Published joint torque limits, N m
constexpr std::array<double, kPandaJoints> kTorqueLimitsNm = {87, 87, 87, 87, 12, 12, 12};

// Small joint damping (N m s/rad) and armature (kg m^2): keep the free dynamics well conditioned
// without pretending to model the real gearboxes
constexpr double kJointDampingNmsPerRad = 0.1;
constexpr double kJointArmatureKgM2 = 0.01;

// Torsional and rolling friction of object contacts, and their solimp (MuJoCo's default)
constexpr double kObjectTorsionalFriction = 0.005;
constexpr double kObjectRollingFriction = 0.0001;
constexpr const char* kObjectSolimp = "0.9 0.95 0.001 0.5 2";

// Contact and constraint buffers of object-only detection: far above the pairs' one contact each
// (3 rows each with elliptic cones) plus 7 joint limits; a fuller buffer raises a MuJoCo warning
constexpr int kObjectOnlyMaxContacts = 50;
constexpr int kObjectOnlyMaxConstraints = 150;

// One moving link's inertial (its DH row is PandaDhRows()[i]).
// Inertials are the feasible parameter set of Gaz, Cognetti, Oliva, Robuffo Giordano, De Luca,
// "Dynamic Identification of the Franka Emika Panda Robot With Retrieval of Feasible Parameters
// Using Penalty-Based Optimization", IEEE RA-L 4(4), 2019: centre of mass in the link (DH) frame,
// inertia about the centre of mass along the link axes. Link 7 is without the hand. The large
// Ixx, Iyy of link 1 are as published: joint 1 only ever sees its Izz.
struct PandaLink {
  double mass_kg;
  std::array<double, 3> com_m;          // link frame
  std::array<double, 6> inertia_kg_m2;  // Ixx Iyy Izz Ixy Ixz Iyz (MJCF fullinertia order)
};
constexpr std::array<PandaLink, kPandaJoints> kPandaLinks = {{
    {4.970684,
     {0.003875, 0.002081, -0.04762},
     {0.70337, 0.70661, 0.009117, -0.000139, 0.006772, 0.019169}},
    {0.646926,
     {-0.003141, -0.02872, 0.003495},
     {0.007962, 0.02811, 0.025995, -0.003925, 0.010254, 0.000704}},
    {3.228604,
     {0.027518, 0.039252, -0.066502},
     {0.037242, 0.036155, 0.01083, -0.004761, -0.011396, -0.012805}},
    {3.587895,
     {-0.05317, 0.104419, 0.027454},
     {0.025853, 0.019552, 0.028323, 0.007796, -0.001332, 0.008641}},
    {1.225946,
     {-0.011953, 0.041065, -0.038437},
     {0.035549, 0.029474, 0.008627, -0.002117, -0.004037, 0.000229}},
    {1.666555,
     {0.060149, -0.014117, -0.010517},
     {0.001964, 0.004354, 0.005433, 0.000109, -0.001158, 0.000341}},
    {0.735522,
     {0.010517, -0.004252, 0.061597},
     {0.012516, 0.010027, 0.004815, -0.000428, -0.001196, -0.000741}},
}};

// Collision capsule in a link frame: segment end points (m) and radius (m). Sized by eye from the
// arm's published outline (housings ~0.12 m across); they bound the links, they do not trace them.
struct Capsule {
  int link;  // 0 = base (world), 1..7 = panda_link1..7
  std::array<double, 6> fromto_m;
  double radius_m;
};
constexpr std::array<Capsule, 11> kCollisionCapsules = {{
    {0, {0, 0, 0.0, 0, 0, 0.06}, 0.07},
    {1, {0, 0, -0.14, 0, 0, 0.0}, 0.06},
    {2, {0, 0, 0.0, 0, -0.2, 0.0}, 0.06},
    {3, {0, 0, -0.16, 0, 0, -0.04}, 0.06},
    {3, {0, 0, 0.0, 0.0825, 0, 0.0}, 0.05},
    {4, {0, 0, -0.06, 0, 0, 0.06}, 0.06},
    {4, {0, 0, 0.0, -0.0825, 0.12, 0.0}, 0.055},
    {5, {0, 0, -0.26, 0, 0, -0.06}, 0.055},
    {6, {0, 0, -0.05, 0, 0, 0.03}, 0.055},
    {6, {0, 0, 0.0, 0.088, 0, 0.0}, 0.05},
    {7, {0, 0, -0.02, 0, 0, 0.08}, 0.045},
}};

// Shortest round-trip text of a number; exact zeros for the cos(pi/2) residue of DH rotations
std::string Num(double value) {
  return fmt::format("{}", std::abs(value) < 1e-15 ? 0.0 : value);
}

std::string Indent(int depth) {
  return std::string(2 * static_cast<size_t>(depth), ' ');
}

// Geom name of kCollisionCapsules[index]: panda_link<link>_collision<k>, k counting in its link
std::string CapsuleName(size_t index) {
  const int link = kCollisionCapsules[index].link;
  int count = 0;
  for (size_t i = 0; i < index; ++i) count += kCollisionCapsules[i].link == link ? 1 : 0;
  return fmt::format("panda_link{}_collision{}", link, count);
}

// <geom> lines of every collision capsule of `link`
std::string CapsuleGeoms(int link, int depth) {
  std::string out;
  for (size_t i = 0; i < kCollisionCapsules.size(); ++i) {
    const Capsule& capsule = kCollisionCapsules[i];
    if (capsule.link != link) continue;
    const auto& f = capsule.fromto_m;
    out += fmt::format(
        "{}<geom name=\"{}\" type=\"capsule\" fromto=\"{} {} {} {} {} {}\" size=\"{}\"/>\n",
        Indent(depth), CapsuleName(i), Num(f[0]), Num(f[1]), Num(f[2]), Num(f[3]), Num(f[4]),
        Num(f[5]), Num(capsule.radius_m));
  }
  return out;
}

void RequirePositive(double value, const char* key) {
  if (!(std::isfinite(value) && value > 0.0)) {
    throw ConfigError(fmt::format("{} = {} must be positive and finite", key, value));
  }
}

// Inputs the MJCF needs positive and finite, refused naming the key.
void CheckMjcfInputs(const TubeConfig& tube, const PandaMjcfOptions& options) {
  RequirePositive(options.timestep_s, "timestep_s");
  RequirePositive(options.tube_density_kg_m3, "tube_density_kg_m3");
  RequirePositive(tube.outer_radius_m, "tube.outer_radius_m");
  RequirePositive(tube.wall_thickness_m, "tube.wall_thickness_m");
  RequirePositive(tube.length_m, "tube.length_m");
  for (const MjcfObject& object : options.objects) {
    if (object.segments.empty()) throw ConfigError("an MJCF object needs at least one segment");
    for (const ObjectSegment& segment : object.segments) {
      RequirePositive(segment.radius_m, "object segment radius_m");
      RequirePositive((segment.p1 - segment.p0).norm(), "object segment length");
    }
    RequirePositive(object.contact_timeconst_s, "object.contact_timeconst_s");
    RequirePositive(object.contact_dampratio, "object.contact_dampratio");
    if (!(std::isfinite(object.friction) && object.friction >= 0.0)) {
      throw ConfigError(fmt::format("object.friction = {} must be non-negative", object.friction));
    }
  }
  tube.Validate();
}

// <mujoco>, compiler, options, sizes and defaults, up to the open <worldbody>.
std::string HeaderXml(const PandaMjcfOptions& options) {
  std::string xml;
  xml += "<mujoco model=\"sonicboom_panda\">\n";
  // angles in radians; every body carries an explicit inertial, geoms add no mass
  xml += "  <compiler angle=\"radian\" inertiafromgeom=\"false\"/>\n";
  // Euler: MuJoCo's Euler already integrates joint damping implicitly, and the motors add no
  // velocity-dependent force, so the "implicit" integrator would only cost more per step
  // "predefined": only the <pair>s below are tested, without the broad phase
  xml += fmt::format("  <option timestep=\"{}\" gravity=\"0 0 {}\" integrator=\"Euler\"{}{}/>\n",
                     Num(options.timestep_s), Num(-kGravityMS2),
                     options.elliptic_friction_cones ? " cone=\"elliptic\"" : "",
                     options.object_contacts_only ? " collision=\"predefined\"" : "");
  // object-only detection bounds the contacts by the pairs (one each for capsules and cylinders),
  // so small constraint buffers do; the solver stack MuJoCo derives from them shrinks from ~10 MB
  // (njmax 500) to well under 1 MB, which mj_makeData no longer has to clear
  if (options.object_contacts_only) {
    xml += fmt::format("  <size nconmax=\"{}\" njmax=\"{}\"/>\n", kObjectOnlyMaxContacts,
                       kObjectOnlyMaxConstraints);
  }
  xml += "  <default>\n";
  xml += fmt::format(
      "    <joint type=\"hinge\" axis=\"0 0 1\" limited=\"true\" damping=\"{}\" "
      "armature=\"{}\"/>\n",
      Num(kJointDampingNmsPerRad), Num(kJointArmatureKgM2));
  xml += "    <geom contype=\"1\" conaffinity=\"1\" rgba=\"0.9 0.9 0.9 1\"/>\n";
  xml += "    <site size=\"0.01\" rgba=\"1 0 0 1\"/>\n";
  xml += "  </default>\n";
  xml += "  <worldbody>\n";
  return xml;
}

// The seven links as nested bodies (left open: the flange goes inside link 7).
std::string ArmXml() {
  std::string xml;
  const JointVector lower_rad = PandaLowerLimits(), upper_rad = PandaUpperLimits();
  // Body i sits at RotX(alpha) TransX(a) TransZ(d) of its parent and turns about its own z:
  // T_i = RotX(alpha) TransX(a) RotZ(q) TransZ(d) = [RotX(alpha) Trans(a, 0, d)] RotZ(q), since
  // TransZ(d) commutes with RotZ(q). So pos = RotX(alpha) (a, 0, d), quat = RotX(alpha).
  for (int i = 0; i < kPandaJoints; ++i) {
    const PandaLink& link = kPandaLinks[i];
    const DhRow& dh = PandaDhRows()[i];
    const int depth = 2 + i;
    const double s = std::sin(dh.alpha_rad), c = std::cos(dh.alpha_rad);
    xml += fmt::format("{}<body name=\"panda_link{}\" pos=\"{} {} {}\" quat=\"{} {} 0 0\">\n",
                       Indent(depth), i + 1, Num(dh.a_m), Num(-dh.d_m * s), Num(dh.d_m * c),
                       Num(std::cos(0.5 * dh.alpha_rad)), Num(std::sin(0.5 * dh.alpha_rad)));
    const auto& com = link.com_m;
    const auto& inertia = link.inertia_kg_m2;
    xml += fmt::format(
        "{}<inertial pos=\"{} {} {}\" mass=\"{}\" fullinertia=\"{} {} {} {} {} {}\"/>\n",
        Indent(depth + 1), Num(com[0]), Num(com[1]), Num(com[2]), Num(link.mass_kg),
        Num(inertia[0]), Num(inertia[1]), Num(inertia[2]), Num(inertia[3]), Num(inertia[4]),
        Num(inertia[5]));
    xml += fmt::format("{}<joint name=\"panda_joint{}\" range=\"{} {}\"/>\n", Indent(depth + 1),
                       i + 1, Num(lower_rad[i]), Num(upper_rad[i]));
    xml += CapsuleGeoms(i + 1, depth + 1);
  }

  return xml;
}

// The flange body on link 7 with the tube.
std::string FlangeXml(const TubeConfig& tube, const PandaMjcfOptions& options) {
  std::string xml;
  // flange body on link 7 with the tube: a thin-walled PVC cylinder centred on flange z
  const int flange_depth = 2 + kPandaJoints;
  const double r_out_m = tube.outer_radius_m, r_in_m = tube.outer_radius_m - tube.wall_thickness_m;
  const double tube_mass_kg =
      options.tube_density_kg_m3 * kPi * (r_out_m * r_out_m - r_in_m * r_in_m) * tube.length_m;
  const double radial_sq_m2 = r_out_m * r_out_m + r_in_m * r_in_m;
  const double tube_izz_kg_m2 = 0.5 * tube_mass_kg * radial_sq_m2;
  const double tube_ixx_kg_m2 =
      tube_mass_kg * (3.0 * radial_sq_m2 + tube.length_m * tube.length_m) / 12.0;
  const std::string tube_pos = fmt::format("0 0 {}", Num(tube.center_from_flange_m));
  xml += fmt::format("{}<body name=\"panda_flange\" pos=\"0 0 {}\">\n", Indent(flange_depth),
                     Num(PandaDhRows()[kPandaJoints].d_m));
  xml += fmt::format("{}<inertial pos=\"{}\" mass=\"{}\" diaginertia=\"{} {} {}\"/>\n",
                     Indent(flange_depth + 1), tube_pos, Num(tube_mass_kg), Num(tube_ixx_kg_m2),
                     Num(tube_ixx_kg_m2), Num(tube_izz_kg_m2));
  xml += fmt::format("{}<site name=\"flange\" pos=\"0 0 0\"/>\n", Indent(flange_depth + 1));
  xml += fmt::format(
      "{}<geom name=\"tube\" type=\"cylinder\" pos=\"{}\" size=\"{} {}\" "
      "rgba=\"0.85 0.85 0.75 1\"/>\n",
      Indent(flange_depth + 1), tube_pos, Num(tube.outer_radius_m), Num(0.5 * tube.length_m));
  xml += fmt::format("{}<site name=\"tube_center\" pos=\"{}\"/>\n", Indent(flange_depth + 1),
                     tube_pos);
  xml += fmt::format("{}</body>\n", Indent(flange_depth));
  return xml;
}

// The struck objects.
std::string ObjectsXml(const PandaMjcfOptions& options) {
  std::string xml;
  // struck objects: mocap bodies (fixed in space, placed per simulation), parked far below the
  // base; one cylinder per segment
  for (size_t i = 0; i < options.objects.size(); ++i) {
    const MjcfObject& object = options.objects[i];
    xml += fmt::format("    <body name=\"object{}\" mocap=\"true\" pos=\"0 0 -10\">\n", i);
    for (size_t k = 0; k < object.segments.size(); ++k) {
      const ObjectSegment& seg = object.segments[k];
      xml += fmt::format(
          "      <geom name=\"object{}_{}\" type=\"cylinder\" fromto=\"{} {} {} {} {} {}\" "
          "size=\"{}\" priority=\"1\" condim=\"3\" friction=\"{} {} {}\" solref=\"{} {}\" "
          "solimp=\"{}\" rgba=\"0.6 0.4 0.2 1\"/>\n",
          i, k, Num(seg.p0.x()), Num(seg.p0.y()), Num(seg.p0.z()), Num(seg.p1.x()), Num(seg.p1.y()),
          Num(seg.p1.z()), Num(seg.radius_m), Num(object.friction), Num(kObjectTorsionalFriction),
          Num(kObjectRollingFriction), Num(object.contact_timeconst_s),
          Num(object.contact_dampratio), kObjectSolimp);
    }
    xml += "    </body>\n";
  }
  return xml;
}

// The <contact> section: exclusions and, for object-only detection, the pairs.
std::string ContactXml(const PandaMjcfOptions& options) {
  std::string xml;
  // links 5 and 7 nest around the wrist on the real arm; their capsules touch near q6 = 0
  xml += "  <contact>\n";
  xml += "    <exclude body1=\"panda_link5\" body2=\"panda_link7\"/>\n";
  // object-only detection: each object geom against the tube and every arm capsule, with the
  // parameters the object's priority gives these contacts (condim 3, friction slide slide spin roll
  // roll)
  if (options.object_contacts_only) {
    std::vector<std::string> arm_geoms = {"tube"};
    for (size_t k = 0; k < kCollisionCapsules.size(); ++k) arm_geoms.push_back(CapsuleName(k));
    for (size_t i = 0; i < options.objects.size(); ++i) {
      const MjcfObject& object = options.objects[i];
      for (size_t k = 0; k < object.segments.size(); ++k) {
        for (const std::string& geom : arm_geoms) {
          xml += fmt::format(
              "    <pair geom1=\"{}\" geom2=\"object{}_{}\" condim=\"3\" "
              "friction=\"{} {} {} {} {}\" solref=\"{} {}\" solimp=\"{}\" margin=\"0\" "
              "gap=\"0\"/>\n",
              geom, i, k, Num(object.friction), Num(object.friction), Num(kObjectTorsionalFriction),
              Num(kObjectRollingFriction), Num(kObjectRollingFriction),
              Num(object.contact_timeconst_s), Num(object.contact_dampratio), kObjectSolimp);
        }
      }
    }
  }
  xml += "  </contact>\n";

  return xml;
}

// The <actuator> section.
std::string ActuatorXml() {
  std::string xml;
  // direct joint torque motors, limited to the published torques
  xml += "  <actuator>\n";
  for (int i = 0; i < kPandaJoints; ++i) {
    xml += fmt::format(
        "    <motor name=\"panda_motor{}\" joint=\"panda_joint{}\" gear=\"1\" "
        "ctrllimited=\"true\" ctrlrange=\"{} {}\"/>\n",
        i + 1, i + 1, Num(-kTorqueLimitsNm[i]), Num(kTorqueLimitsNm[i]));
  }
  xml += "  </actuator>\n";
  return xml;
}

}  // namespace

double PandaLinkMassSumKg() {
  double sum_kg = 0.0;
  for (const PandaLink& link : kPandaLinks) sum_kg += link.mass_kg;
  return sum_kg;
}

std::string PandaMjcf(const TubeConfig& tube, const PandaMjcfOptions& options) {
  CheckMjcfInputs(tube, options);
  std::string xml = HeaderXml(options);
  xml += CapsuleGeoms(0, 2);
  xml += ArmXml();
  xml += FlangeXml(tube, options);
  for (int i = kPandaJoints - 1; i >= 0; --i) xml += fmt::format("{}</body>\n", Indent(2 + i));
  xml += ObjectsXml(options);
  xml += "  </worldbody>\n";
  xml += ContactXml(options);
  xml += ActuatorXml();
  xml += "</mujoco>\n";
  return xml;
}

}  // namespace sonicboom::sim
