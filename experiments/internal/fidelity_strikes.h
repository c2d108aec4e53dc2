#pragma once
// The fidelity ladder's test strikes, and the whole production strike through them: its time per
// strike over the record and over the span the features read (acoustics.render_span). Private to
// experiments.

#include <cstdint>
#include <string>

#include <nlohmann/json.hpp>

#include "sonicboom/core/sample.h"
#include "sonicboom/experiments/config.h"

namespace sonicboom::experiments {

// a test strike: a wooden rod crossing the tube (rigid striker) at (z, theta)
struct TestStrike {
  double z_m, theta_rad, speed_m_s, mass_kg;
};
inline constexpr TestStrike kStrikes[] = {{0.05, 0.3, 0.1, 0.03},  {-0.08, 2.0, 0.3, 0.03},
                                          {0.0, -1.2, 1.0, 0.03},  {0.09, 3.0, 0.05, 0.1},
                                          {-0.1, -2.8, 0.5, 0.02}, {0.03, 1.4, 0.2, 0.05}};

/// The contact of a test strike at time_s from the record start.
ContactEvent StrikeEvent(const TestStrike& s, double time_s);

/// The production renderer's settings for the whole-strike timings: the config's acoustics, on
/// the grid arc_m x axial_m when quick (else the configured grid).
struct WholeStrikeSetup {
  const SonicBoomConfig* config{nullptr};
  double arc_m{0.0}, axial_m{0.0};
  bool quick{false};
  int64_t strikes{4};  // test strikes cycled through
};

/// The whole default strike (contact solve with the rod's bending modes, modes, DAQ) through
/// the production renderer, 40 times, each timed alone: the median ms per strike, and the
/// median of it in the vibration model.
struct WholeStrikeTime {
  double ms{0.0}, vibration_ms{0.0};
};
WholeStrikeTime WholeStrikeMs(const WholeStrikeSetup& setup);

/// "What a scene needs": the whole strike rendered over the record and over the span each of two
/// feature sets reads (the configured features, and a 20 ms waveform window as
/// configs/transfer.yaml's), each timed, and the two renders' features compared. Appends the
/// section to md; returns its rows.
nlohmann::json RenderSpanSection(const WholeStrikeSetup& setup, std::string* md);

/// A scene that plays a fixed band (acoustics.max_frequency_hz = band_hz) on a derived grid
/// (shell.grid_spacing_m = axial_spacing_m = 0), resolved as ResolveConfig resolves it: its
/// config (the square grid's spacing in shell.grid_spacing_m) and the band its modes are solved
/// to.
struct FixedBandScene {
  SonicBoomConfig config;
  double solved_band_hz{0.0};
};
FixedBandScene SceneOfBand(const SonicBoomConfig& config, double band_hz);

/// The fixed bands the ladder shows on derived grids, Hz.
inline constexpr double kDerivedGridBandsHz[] = {10000.0, 5000.0, 2000.0};

/// "What a scene needs", the mode solve: the configured grid to its full band against each fixed
/// band's derived grid to its solved band, each solved afresh (no cache) and timed: DOFs, modes,
/// seconds, and the whole strike's ms through the production renderer. Appends to md; returns
/// its rows.
nlohmann::json ModeBandSection(const WholeStrikeSetup& setup, std::string* md);

}  // namespace sonicboom::experiments
