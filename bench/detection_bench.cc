// Strike detection at low SNR (dsp::CheckStrike): detection rate over peak-to-noise for hard and
// soft strikers, false alarms per background kind; prints a Markdown table (docs/robustness.md,
// scripts/detection_table.sh).
//
// Strikes: clean six-channel records of the default tube (acoustics::StrikeSynthesizer, every
// noise source off, 24-bit output), each channel about its mean, scaled so that the peak over
// channels stands the cell's dB above the background's RMS, plus a background drawn per record.
// Backgrounds: a white DAQ floor; mains hum; arm motion (the motor and gear tones of
// acoustics::DaqChain following a joint speed that ramps up and down); hum and arm motion
// together; each over the floor. Every draw comes from (seed, record index).
//
//   detection_bench [--records N] [--strikes K] [--seed S]
#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <string>
#include <vector>

#include "sonicboom/acoustics/daq.h"
#include "sonicboom/acoustics/synth.h"
#include "sonicboom/core/rng.h"
#include "sonicboom/dsp/features.h"

namespace sonicboom {
namespace {

constexpr double kFloorV = 3.6e-5;  // the DAQ floor: hypot(ambient 30 uV, preamp 20 uV)
constexpr double kSpeedRateHz = 100.0;
const std::vector<double> kSnrDb = {14, 17, 20, 25, 30, 40};

enum class Background { kWhite, kHum, kArm, kMix };
const char* Name(Background b) {
  switch (b) {
    case Background::kWhite: return "white floor";
    case Background::kHum: return "hum + floor";
    case Background::kArm: return "arm motion + floor";
    case Background::kMix: return "hum + arm motion + floor";
  }
  return "";
}

// Index blocks of the draws, so that no two cells share a seed
constexpr uint64_t kStrikeBlock = 1'000'000, kCellBlock = 10'000'000;

struct Options {
  int64_t records{200};  // per cell
  int64_t strikes{20};   // distinct strikes per striker kind
  uint64_t seed{1};
};

Options Parse(int argc, char** argv) {
  Options o;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string key = argv[i];
    const long long value = std::atoll(argv[i + 1]);
    if (key == "--records") o.records = std::max(1LL, value);
    else if (key == "--strikes") o.strikes = std::max(1LL, value);
    else if (key == "--seed") o.seed = static_cast<uint64_t>(value);
  }
  return o;
}

// One clean strike (C x T, each channel about its mean, peak over channels 1) and its contact
struct CleanStrike {
  Eigen::MatrixXf audio;
  double contact_s{0.0};  // Hertz duration of the impact on a rigid wall
  int64_t arrival{0};     // first sample where a channel reaches 1 % of the peak
};

// A striker of kind soft (tip modulus 1-100 MPa) or hard (0.5-200 GPa, randomized.yaml's
// range), at a random place, time, speed and mass
CleanStrike RenderStrike(const acoustics::StrikeSynthesizer& synth,
                         const acoustics::AcousticModelConfig& config, bool soft, uint64_t seed) {
  Rng rng(seed, Stream::kStrike);
  const auto log_uniform = [&](double lo, double hi) {
    return std::exp(rng.Uniform(std::log(lo), std::log(hi)));
  };
  ContactEvent c;
  c.time_s = rng.Uniform(0.3, 1.6);
  c.z_m = rng.Uniform(-0.1, 0.1);
  c.theta_rad = rng.Uniform(-3.14159, 3.14159);
  c.normal_speed_m_s = log_uniform(0.05, 0.5);
  c.effective_mass_kg = log_uniform(0.01, 0.1);
  c.striker_radius_m = log_uniform(0.003, 0.02);
  c.striker_youngs_modulus_pa = soft ? log_uniform(1e6, 1e8) : log_uniform(5e8, 2e11);
  c.striker_poisson_ratio = soft ? 0.45 : 0.3;
  const acoustics::RenderedStrike r = synth.Render(c, {}, kSpeedRateHz, seed);
  CleanStrike out;
  out.audio = r.audio.colwise() - r.audio.rowwise().mean();
  out.audio /= out.audio.cwiseAbs().maxCoeff();
  out.contact_s = acoustics::SolveHertzImpact(c, config.tube, config.material).duration_s;
  while (out.arrival + 1 < out.audio.cols() &&
         out.audio.col(out.arrival).cwiseAbs().maxCoeff() < 0.01f)
    ++out.arrival;
  return out;
}

// A joint speed (rad/s at kSpeedRateHz over the record) that ramps linearly from rest to a top
// speed, holds, and ramps back to rest within the record
std::vector<double> JointSpeed(Rng* rng, double record_s) {
  const double top = rng->Uniform(0.2, 2.0);
  const double up = rng->Uniform(0.1, 0.5), hold = rng->Uniform(0.0, 0.5);
  const double down = rng->Uniform(0.1, 0.5);
  const double start = rng->Uniform(0.0, std::max(0.0, record_s - up - hold - down));
  std::vector<double> speed(static_cast<size_t>(record_s * kSpeedRateHz) + 1);
  for (size_t i = 0; i < speed.size(); ++i) {
    const double t = i / kSpeedRateHz - start;
    const double rise = std::clamp(t / up, 0.0, 1.0);
    const double fall = std::clamp((up + hold + down - t) / down, 0.0, 1.0);
    speed[i] = top * std::min(rise, fall);
  }
  return speed;
}

// One background record (C x T, volts): hum and arm motion through the DAQ chain (no noise of
// its own), then the white floor
Eigen::MatrixXf RenderBackground(const acoustics::DaqChain& daq, Background kind, uint64_t seed,
                                 int channels, int64_t frames, double fs) {
  Rng rng(seed, Stream::kNoise);
  acoustics::ChainDraw chain;
  chain.noise_floor_v = 0.0;
  std::vector<double> speed;
  if (kind == Background::kHum || kind == Background::kMix) {
    chain.hum_hz = (rng.Uniform() < 0.5 ? 50.0 : 60.0) + rng.Uniform(-0.2, 0.2);
    chain.hum_rms_v = std::exp(rng.Uniform(std::log(1e-4), std::log(3e-3)));
    for (int h = 0; h < 5; ++h) chain.hum_phase_rad.push_back(rng.Uniform(0.0, 6.2831853));
    for (int c = 0; c < channels; ++c) chain.hum_channel_scale.push_back(rng.Uniform(0.5, 1.5));
  }
  if (kind == Background::kArm || kind == Background::kMix) speed = JointSpeed(&rng, frames / fs);
  Eigen::MatrixXf audio = Eigen::MatrixXf::Zero(channels, frames);
  if (kind != Background::kWhite)
    daq.Convert(Eigen::MatrixXd::Zero(channels, frames), speed, kSpeedRateHz, seed, &audio, chain);
  for (Eigen::Index i = 0; i < audio.size(); ++i)
    audio.data()[i] += static_cast<float>(kFloorV * rng.Normal());
  return audio;
}

// RMS over every channel and sample, each channel about its mean
double Rms(const Eigen::MatrixXf& x) {
  const Eigen::MatrixXf centred = x.colwise() - x.rowwise().mean();
  return std::sqrt(centred.cast<double>().squaredNorm() / static_cast<double>(x.size()));
}

// The background's RMS where the strike lands: the 100 ms about its first arrival, each channel
// about its mean over the record (hum and arm motion are not stationary: a strike that lands
// while the arm is at speed has that level around it, not the record's)
double LocalRms(const Eigen::MatrixXf& x, int64_t arrival, double fs) {
  const int64_t half = std::llround(0.05 * fs);
  const int64_t from = std::clamp<int64_t>(arrival - half, 0, x.cols() - 1);
  const int64_t to = std::clamp<int64_t>(arrival + half, from + 1, x.cols());
  const Eigen::MatrixXf centred = x.colwise() - x.rowwise().mean();
  const Eigen::MatrixXf part = centred.middleCols(from, to - from);
  return std::sqrt(part.cast<double>().squaredNorm() / static_cast<double>(part.size()));
}

// The rule CheckStrike applied before (issue 59): the loudest frame_s frame of the all-channel
// energy 20 dB above the median frame, each channel about its mean (the cut-off test left out)
bool OldRuleFound(const Eigen::MatrixXf& x, double fs, double frame_s) {
  const Eigen::MatrixXf centred = x.colwise() - x.rowwise().mean();
  const int64_t frame = std::llround(frame_s * fs);
  std::vector<double> energy;
  for (int64_t start = 0; start + frame <= x.cols(); start += frame)
    energy.push_back(centred.middleCols(start, frame).cast<double>().squaredNorm());
  const double peak = *std::max_element(energy.begin(), energy.end());
  std::nth_element(energy.begin(), energy.begin() + energy.size() / 2, energy.end());
  return 10.0 * std::log10(peak / energy[energy.size() / 2]) >= 20.0;
}

std::string Percent(int64_t hits, int64_t n) {
  return fmt::format("{:.1f} %", 100.0 * static_cast<double>(hits) / static_cast<double>(n));
}

// Detection rates of one striker kind over one background, one per kSnrDb: by CheckStrike, and
// by the old rule with a 2.9 ms frame (the default features.onset_frame_s)
struct Rates {
  std::vector<std::string> found, old_rule;
};
// How a strike is scaled against its background: to the record's RMS, or to the RMS about it
enum class Scale { kRecord, kLocal };
Rates DetectionRow(const std::vector<CleanStrike>& strikes, const acoustics::DaqChain& daq,
                   Background background, Scale scale, uint64_t cell, const Options& o,
                   double fs) {
  Rates rates;
  for (size_t s = 0; s < kSnrDb.size(); ++s) {
    int64_t found = 0, old_found = 0;
    for (int64_t r = 0; r < o.records; ++r) {
      const CleanStrike& strike = strikes[static_cast<size_t>(r % o.strikes)];
      const uint64_t seed = SampleSeed(o.seed, (cell + s) * kCellBlock + r);
      Eigen::MatrixXf x = RenderBackground(daq, background, seed,
                                           static_cast<int>(strike.audio.rows()),
                                           strike.audio.cols(), fs);
      const double rms = scale == Scale::kRecord ? Rms(x) : LocalRms(x, strike.arrival, fs);
      x += strike.audio * static_cast<float>(rms * std::pow(10.0, kSnrDb[s] / 20.0));
      found += dsp::CheckStrike(x, fs).found ? 1 : 0;
      old_found += OldRuleFound(x, fs, 0.0029) ? 1 : 0;
    }
    rates.found.push_back(Percent(found, o.records));
    rates.old_rule.push_back(Percent(old_found, o.records));
  }
  return rates;
}

// Contact durations of a set of strikes, "a-b ms"
std::string ContactRange(const std::vector<CleanStrike>& strikes) {
  double lo = 1e9, hi = 0.0;
  for (const CleanStrike& s : strikes) {
    lo = std::min(lo, s.contact_s);
    hi = std::max(hi, s.contact_s);
  }
  return fmt::format("{:.2f}-{:.2f} ms", 1e3 * lo, 1e3 * hi);
}

int Run(const Options& o) {
  const auto begin = std::chrono::steady_clock::now();
  // the default tube with every noise source off (the backgrounds are added per record)
  acoustics::AcousticModelConfig config;
  config.noise.ambient_rms_v = 0.0;
  config.noise.motor_rms_v_per_rad_s = 0.0;
  config.daq.preamp_noise_v = 0.0;
  config.daq.output_bits = 24;
  const acoustics::StrikeSynthesizer synth(config);
  const double fs = config.audio.sample_rate_hz;
  std::vector<CleanStrike> hard, soft;
  for (int64_t i = 0; i < o.strikes; ++i) {
    hard.push_back(RenderStrike(synth, config, false, SampleSeed(o.seed, kStrikeBlock + i)));
    soft.push_back(RenderStrike(synth, config, true, SampleSeed(o.seed, 2 * kStrikeBlock + i)));
  }
  // the backgrounds' chain: motor tones as configured by default, no noise of its own
  acoustics::NoiseConfig noise;
  noise.ambient_rms_v = 0.0;
  acoustics::DaqConfig daq_config = config.daq;
  const int channels = static_cast<int>(hard.front().audio.rows());
  const int64_t frames = hard.front().audio.cols();
  const acoustics::DaqChain daq(daq_config, noise, channels, fs, frames);

  fmt::print("Detection: strikes found by `dsp::CheckStrike` (default rule), {} records a cell "
             "({} distinct strikes a kind, each channel about its mean), the peak over channels "
             "this many dB above the background's RMS:\n\n",
             o.records, o.strikes);
  fmt::print("| strikes | background |");
  for (double db : kSnrDb) fmt::print(" {:.0f} dB |", db);
  fmt::print("\n|---|---|");
  for (size_t i = 0; i < kSnrDb.size(); ++i) fmt::print("---|");
  fmt::print("\n");
  uint64_t cell = 0;
  for (const auto& [label, strikes] :
       {std::pair<std::string, const std::vector<CleanStrike>*>{
            fmt::format("hard (tip 0.5-200 GPa, Hertz contacts {})", ContactRange(hard)), &hard},
        {fmt::format("soft (tip 1-100 MPa, Hertz contacts {})", ContactRange(soft)), &soft}}) {
    for (Background b : {Background::kWhite, Background::kMix}) {
      const Rates rates = DetectionRow(*strikes, daq, b, Scale::kRecord, cell, o, fs);
      cell += kSnrDb.size();
      fmt::print("| {} | {} | {} |\n", label, Name(b), fmt::join(rates.found, " | "));
      if (b == Background::kMix) {
        // the same records, the strike scaled to the background about it
        const Rates local = DetectionRow(*strikes, daq, b, Scale::kLocal, cell - kSnrDb.size(),
                                         o, fs);
        fmt::print("| (scaled to the background's RMS in the 100 ms about the strike) | {} | {} "
                   "|\n",
                   Name(b), fmt::join(local.found, " | "));
      }
      if (b == Background::kWhite) {
        fmt::print("| (old rule: 2.9 ms frame 20 dB above the median frame) | {} | {} |\n",
                   Name(b), fmt::join(rates.old_rule, " | "));
      }
    }
  }
  // false alarms: the backgrounds alone, and how far their loudest peak stands above their noise
  fmt::print("\nFalse alarms: background-only records called strikes, {} records a kind; as "
             "CheckStrike measures them, the loudest peak over the noise RMS and the best rise "
             "(of channels whose peak stands 17 dB above their noise; 0 where none), median and "
             "max:\n\n",
             o.records);
  fmt::print("| background | false alarms | peak over noise RMS | rise |\n|---|---|---|---|\n");
  for (Background b : {Background::kWhite, Background::kHum, Background::kArm, Background::kMix}) {
    int64_t alarms = 0;
    std::vector<double> peak_db, rise_db;
    for (int64_t r = 0; r < o.records; ++r) {
      const Eigen::MatrixXf x = RenderBackground(daq, b, SampleSeed(o.seed, cell * kCellBlock + r),
                                                 channels, frames, fs);
      const dsp::StrikeCheck check = dsp::CheckStrike(x, fs);
      alarms += check.found ? 1 : 0;
      peak_db.push_back(check.peak_to_noise_db);
      rise_db.push_back(check.rise_db);
    }
    ++cell;
    const auto median_max = [](std::vector<double> v) {
      std::sort(v.begin(), v.end());
      return fmt::format("{:.1f} dB, {:.1f} dB", v[v.size() / 2], v.back());
    };
    fmt::print("| {} | {} ({}/{}) | {} | {} |\n", Name(b), Percent(alarms, o.records), alarms,
               o.records, median_max(peak_db), median_max(rise_db));
  }
  const double s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - begin).count();
  fmt::print("\n({:.0f} s on one core, seed {})\n", s, o.seed);
  return 0;
}

}  // namespace
}  // namespace sonicboom

int main(int argc, char** argv) {
  return sonicboom::Run(sonicboom::Parse(argc, argv));
}
