#pragma once
/// Randomized structures and sensor chains (docs/randomization.md): per-sample draws of what a
/// real build varies and that the renderer can apply exactly without a new mode solve.
///   - material: Young's modulus (with a temperature shift), density, loss factor and the
///     exponent of its frequency law. At fixed geometry and Poisson ratio K scales with E and M
///     with rho, so the modes keep their shapes, frequencies scale by sqrt(E'/E / (rho'/rho)),
///     mass-normalized shapes by 1/sqrt(rho'/rho) and the static flexibility by E/E'.
///   - the striker: effective mass, tip radius, tip modulus and approach speed, hence the contact
///     duration and force.
///   - the sensor chain: per-channel bonding (sensitivity) and preamp gain, per-channel high-pass
///     corner, noise floor, mains hum and its harmonics, record level and converter full scale.
/// Every range is a list [min, max]; an empty list leaves that quantity as configured. Every
/// draw comes from (sample seed, Stream::kRandomize) in a fixed order, whichever ranges are set,
/// so turning one range on never changes another's numbers. The drawn values are stored with
/// each sample (Variation::Values, names from VariationNames).

#include <cstdint>
#include <string>
#include <vector>

#include "sonicboom/acoustics/shell.h"
#include "sonicboom/core/archive.h"
#include "sonicboom/core/tube.h"

namespace sonicboom::acoustics {

/// Keys under "randomize". Ranges are [min, max] (inclusive); [] = not randomized.
struct RandomizeConfig {
  // material of the tube
  std::vector<double> youngs_modulus_scale;  // x material.youngs_modulus_pa, uniform
  std::vector<double> density_scale;         // x material.density_kg_m3, uniform
  std::vector<double> temperature_c;         // uniform; E x (1 + modulus_per_c (T - reference))
  double modulus_per_c{-0.004};              // relative modulus change per kelvin (rigid PVC)
  double reference_temperature_c{20.0};      // the temperature material.youngs_modulus_pa holds at
  // either range replaces the shell's Rayleigh damping by the law
  // eta(f) = material.loss_factor x scale x (f / loss_reference_hz)^exponent for every mode
  std::vector<double> loss_factor_scale;  // log-uniform
  std::vector<double> loss_exponent;      // uniform
  double loss_reference_hz{2000.0};
  // the striker at the first contact and every other impact of the record
  std::vector<double> striker_mass_scale;         // x effective mass (rigid strikers), log-uniform
  std::vector<double> striker_radius_m;           // tip radius of curvature, log-uniform
  std::vector<double> striker_youngs_modulus_pa;  // tip modulus, log-uniform
  std::vector<double> speed_scale;                // x approach speed, uniform
  // sensor chain, drawn per channel where the name says so
  std::vector<double> sensitivity_scale;  // per channel: disc bonding, log-uniform
  std::vector<double> channel_gain_db;    // per channel: preamp gain offset, uniform
  std::vector<double> highpass_hz;        // per channel: input high-pass corner, log-uniform
  std::vector<double> noise_floor_v;      // ambient + preamp floor (rms), log-uniform
  std::vector<double> hum_hz;             // mains fundamental, uniform (e.g. [49.8, 60.2])
  std::vector<double> hum_rms_v;          // hum level (rms of all harmonics), log-uniform
  int64_t hum_harmonics{5};               // odd and even harmonics 1..N, amplitudes 1/k
  std::vector<double> record_level_db;    // gain of every channel, uniform
  std::vector<double> full_scale_scale;   // x daq.full_scale_v (converter scaling), uniform
  // microphone placement, drawn per sample and channel (the cheap, exact part of a build's
  // variation: only the sensor rows change)
  std::vector<double> mic_z_offset_m;        // per channel: axial offset of the disc, uniform
  std::vector<double> mic_theta_offset_deg;  // per channel: angular offset, uniform
  std::vector<double> disc_diameter_m;       // per channel: the bonded disc's diameter, uniform
  // the structure itself: a pool of `structure_variants` structures, each drawn once from the
  // global seed and its variant number, their modes by a Ritz projection onto the base modes
  // (shell_ritz.h); every sample picks one variant. 0 = the configured structure only.
  int64_t structure_variants{0};
  std::vector<double> bolt_count;            // bolts per seam, integer, uniform
  std::vector<double> bolt_z_jitter_m;       // offset of each bolt from even spacing, uniform
  std::vector<double> bolt_stiffness_scale;  // per bolt: x shell.bolt_stiffness_n_m, log-uniform
  std::vector<double> flange_mount_scale;    // x shell.flange_mount_stiffness_n_m2, log-uniform
  std::vector<double> tool_mount_scale;      // x shell.tool_mount_stiffness_n_m2, log-uniform
  std::vector<double> poisson_ratio;         // material.poisson_ratio, uniform
  // masses a hand build glues or clamps on the wall (shell.attached_mass_*): a count of them
  // (integer, uniform, at most kMaxAttachedMasses), each of a mass (log-uniform) at a place
  // drawn uniformly over the wall; and each disc's own load (the disc with its epoxy, solder and
  // leads) at its mark, per disc, uniform
  std::vector<double> attached_mass_count;
  std::vector<double> attached_mass_kg;
  std::vector<double> disc_mass_kg;
  // another theory in the training set: this fraction of the strikes (drawn per sample) is
  // rendered by the reference solid (docs/reference_model.md) with its own striker, damping and
  // sensor chain instead of this model; its modes up to reference_max_frequency_hz on elements of
  // reference_element_m, solved once and kept in the mode cache
  double reference_fraction{0.0};
  double reference_max_frequency_hz{15000.0};
  double reference_element_m{0.0135};
  // what a tube as built adds (docs/randomization.md, "As built"); drawn after everything above,
  // so that setting them leaves every other draw of a sample as it was
  // a share of soft strikers (rubber tips, fingertips, fruit, leaves): the tip modulus drawn from
  // soft_striker_youngs_modulus_pa (log-uniform) instead; contacts of milliseconds
  double soft_striker_fraction{0.0};
  std::vector<double> soft_striker_youngs_modulus_pa;
  // the white floor set per sample so that the strike's peak (the loudest channel after the
  // chain's gains and filters, before hum) stands this many dB above its rms; uniform; replaces
  // noise_floor_v
  std::vector<double> peak_to_noise_db;
  // filter orders of the chain: the input high-pass as the disc's first-order RC or a
  // second-order Butterworth (an AC-coupled preamp stage), and an anti-alias low-pass in front
  // of the converter (corner log-uniform, order 1 or 2); orders are whole numbers, uniform
  std::vector<double> highpass_order;
  std::vector<double> lowpass_hz;
  std::vector<double> lowpass_order;

  void Serialize(Archive* a);
  /// Ranges have 0 or 2 entries with min <= max, inside physical limits; throws ConfigError
  /// naming the key (randomize.<name>).
  void Validate() const;
  /// Whether any material range is set (they need the numerical-mode rung).
  bool material() const;
  /// Refuses a loss law whose damping ratio reaches 1 (overdamped) in [20 Hz, 20 kHz] for
  /// material.loss_factor = base_loss_factor; names the keys.
  void CheckLossLaw(double base_loss_factor) const;
  /// Whether any range is set (reference_fraction is not a range: it picks a renderer).
  bool any() const;
  /// Whether a structure pool is asked for (structure_variants > 0).
  bool structure() const { return structure_variants > 0; }
  /// Whether the microphone placement is drawn.
  bool mic_placement() const;
};

/// The most masses randomize.attached_mass_count draws.
inline constexpr int64_t kMaxAttachedMasses = 8;

/// One structure variant of the pool: the shell and material it was drawn to, and the drawn
/// values (StructureValueNames' order).
struct StructureVariant {
  ShellConfig shell;
  double poisson_ratio{0.0};
  std::vector<double> values;
};

/// Names of a variant's stored values: "structure_variant" (its number), then one per set
/// structure range (bolt_stiffness_scale: the geometric mean over the bolts; attached_mass_kg:
/// the total attached; disc_mass_kg: the mean over the discs).
std::vector<std::string> StructureValueNames(const RandomizeConfig& config);

/// The configured structure a pool's variants are drawn from.
struct StructureBase {
  const TubeConfig& tube;
  const ShellConfig& shell;
  const MicArrayConfig& mics;  // the discs' marks (their loads sit there)
  double poisson_ratio{0.0};
};

/// Variant `variant` of the pool drawn under global_seed from the base: bolts evenly spaced
/// between the base's first and last bolt (the centre for one) plus the jitter, each with its own
/// stiffness scale; mounts scaled; attached masses at uniform places of the wall (one that would
/// sit within a hole's diameter of a hole's centre is moved a diameter and a half towards the
/// tube's middle) and a load at each disc's mark, added to the base's own attached masses.
/// Depends on nothing else, so every thread, shard and run draws the same pool.
StructureVariant DrawStructure(const RandomizeConfig& config, const StructureBase& base,
                               uint64_t global_seed, int64_t variant);

/// The structure part of a sample's draws: how the modes it is played on differ from the solved
/// ones. Default-constructed, it is the configured structure (Nominal()).
struct StructureDraw {
  double youngs_modulus_scale{1.0};  // total, temperature included
  double density_scale{1.0};
  double temperature_c{20.0};
  // loss law eta(f) = loss_factor (f / loss_reference_hz)^loss_exponent for every mode;
  // loss_factor 0: the shell's own damping (shell.loss_*) at the scaled frequencies
  double loss_factor{0.0};
  double loss_exponent{0.0};
  double loss_reference_hz{2000.0};
  std::vector<double> mic_z_offset_m;        // (channels); empty = the configured placement
  std::vector<double> mic_theta_offset_deg;  // (channels)
  std::vector<double> disc_diameter_m;       // (channels); empty = mics.disc_diameter_m
  int64_t structure_variant{-1};             // the pool's variant; -1 = the configured structure

  /// Frequency factor of every mode: sqrt(E'/E / (rho'/rho)).
  double frequency_scale() const;
  /// Damping ratio of a mode at f Hz (the varied frequency) under the loss law; only when
  /// loss_factor > 0.
  double DampingRatio(double frequency_hz) const;
  /// Whether a disc is moved or resized.
  bool placed() const;
  /// Whether the sample plays the solved modes as they are: nothing scaled, no loss law, no
  /// pool variant, no disc moved. Only the numerical modal rung follows anything else.
  bool Nominal() const;
};

/// The striker part: what hits the tube, relative to the simulated contact.
struct StrikerDraw {
  double mass_scale{1.0};          // a rigid striker's mass (a rod keeps its beam modes)
  double radius_m{0.0};            // tip radius; 0 = as the contact says
  double youngs_modulus_pa{0.0};   // 0 = as the contact says
  double speed_scale{1.0};         // approach speed of every impact
};

/// The sensor-chain part. Default-constructed, it is the configured chain.
struct ChainDraw {
  std::vector<double> sensitivity_scale;  // (channels) bonding; empty = 1
  std::vector<double> channel_gain_db;    // (channels); empty = the DAQ's own draw
  std::vector<double> highpass_hz;        // (channels); empty = daq's R C corner
  double noise_floor_v{-1.0};             // < 0 = as configured
  double hum_hz{50.0};
  double hum_rms_v{0.0};                  // 0 = no hum
  std::vector<double> hum_phase_rad;      // (hum harmonics) not stored
  std::vector<double> hum_channel_scale;  // (channels) pickup of each cable, not stored
  double record_level_db{0.0};
  double full_scale_scale{1.0};
  double peak_to_noise_db{-1.0};  // < 0 = the floor is noise_floor_v (or as configured)
  int highpass_order{1};          // 1: the RC corner; 2: a Butterworth pair at the same corner
  double lowpass_hz{0.0};         // 0 = no anti-alias low-pass
  int lowpass_order{1};
  /// Whether the chain filters or sets its floor in a way the first-order default does not.
  bool shaped() const { return highpass_order != 1 || lowpass_hz > 0.0 || peak_to_noise_db >= 0; }
};

/// The draws of one sample, by the stage that reads them. Fields hold the configured value
/// where a range is not set; a default-constructed Variation is the configured set-up.
struct Variation {
  StructureDraw structure;
  StrikerDraw striker;
  ChainDraw chain;
  std::vector<double> values;  // the set ranges' draws, as VariationNames
};

/// Names of the stored draws: one per set range, per-channel ranges one per channel with the
/// channel appended ("sensitivity_scale_0"), then the microphone placement, then the structure
/// variant's values (StructureValueNames). Empty when nothing is randomized.
std::vector<std::string> VariationNames(const RandomizeConfig& config, int channels);

/// The draws of the sample with this seed (the same seed gives the same numbers on any thread);
/// base_loss_factor is material.loss_factor, the loss law's level before its scale. The
/// structure variant is picked uniformly; its values are not in `values` (the pool holds them:
/// the caller appends StructureVariant::values).
Variation DrawVariation(const RandomizeConfig& config, double base_loss_factor, int channels,
                        uint64_t sample_seed);

/// The tube's material under a draw (modulus and density scaled, loss unchanged).
MaterialConfig VariedMaterial(const MaterialConfig& base, const StructureDraw& v);

}  // namespace sonicboom::acoustics
