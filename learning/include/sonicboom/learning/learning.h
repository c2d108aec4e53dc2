#pragma once
/// Learning: the multimodal localization network (libtorch stays inside learning/*.cc),
/// training, evaluation and localization. Inputs are features already computed by
/// sonicboom::dsp::FeatureExtractor plus proprioception windows.

#include <cstdint>
#include <limits>
#include <map>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "sonicboom/core/archive.h"

namespace sonicboom::learning {

/// The audio encoder: over the (channels x rows x frames) image, the compact CNN or
/// ResNet-18/50 with one input channel per mic; or conv1d, strided 1-D convolutions over time
/// with every (mic, row) as an input channel, made for the waveform representation
/// (features.audio_representation): each record is scaled to unit RMS first, so the record's
/// level does not matter, only the relative levels and timing of the channels.
enum class AudioEncoderKind { kCompact, kResnet18, kResnet50, kConv1d };
inline constexpr EnumName<AudioEncoderKind> kAudioEncoderKindNames[] = {
    {AudioEncoderKind::kCompact, "compact"},
    {AudioEncoderKind::kResnet18, "resnet18"},
    {AudioEncoderKind::kResnet50, "resnet50"},
    {AudioEncoderKind::kConv1d, "conv1d"}};
inline std::span<const EnumName<AudioEncoderKind>> EnumNames(AudioEncoderKind) {
  return kAudioEncoderKindNames;
}

/// The GCC-PHAT token: mlp (the whole (rows x lags) map flattened into three linear layers) or
/// conv (three 1-D convolutions over the lags, the rows as channels, then one linear layer: far
/// fewer weights, less room to memorize one structure's correlation details).
enum class GccEncoderKind { kMlp, kConv };
inline constexpr EnumName<GccEncoderKind> kGccEncoderKindNames[] = {
    {GccEncoderKind::kMlp, "mlp"}, {GccEncoderKind::kConv, "conv"}};
inline std::span<const EnumName<GccEncoderKind>> EnumNames(GccEncoderKind) {
  return kGccEncoderKindNames;
}

/// Arrival picks (waveform features only): per disc, where the smoothed energy of the window
/// first reaches a fixed fraction of that disc's own peak, taken from the network's waveform
/// input itself (so every augmentation moves them with the samples) and read as times relative
/// to the discs' mean and as those times over their spread (a group-speed scale divides out):
/// none; token, one more token beside the waveform's; only, the picks' token in place of the
/// waveform encoder (an ablation: what the timing alone carries).
enum class ArrivalPicks { kNone, kToken, kOnly };
inline constexpr EnumName<ArrivalPicks> kArrivalPicksNames[] = {
    {ArrivalPicks::kNone, "none"}, {ArrivalPicks::kToken, "token"}, {ArrivalPicks::kOnly, "only"}};
inline std::span<const EnumName<ArrivalPicks>> EnumNames(ArrivalPicks) {
  return kArrivalPicksNames;
}

/// Network shape. Cheaper settings trade accuracy for speed.
struct ModelConfig {
  AudioEncoderKind audio_encoder{AudioEncoderKind::kCompact};
  int64_t width{256};  // transformer width (token size)
  int64_t blocks{6};   // pre-norm transformer blocks
  int64_t heads{8};
  double dropout{0.1};
  std::vector<std::string> modalities{"audio", "gcc", "proprio"};  // any non-empty subset
  int64_t crop_frames{345};  // mel frames seen by the network (centre crop)
  GccEncoderKind gcc_encoder{GccEncoderKind::kMlp};
  ArrivalPicks arrival_picks{ArrivalPicks::kNone};  // needs audio in modalities
  // Answer by the layout's symmetry (LocalizerOptions::turn_average) whenever the model is used;
  // inference only (the weights do not depend on it). Needs modalities = [audio].
  bool turn_average{false};
  // With turn_average, each turn also read mirrored (LocalizerOptions::mirror_average).
  bool mirror_average{false};

  void Serialize(Archive* a);
  /// Checks every field and the cross-field rules (heads divide width, known modalities);
  /// throws ConfigError naming the key as "model.<field>".
  void Validate() const;
};

/// Optimisation and augmentation.
struct TrainConfig {
  int64_t epochs{100};
  int64_t batch_size{64};
  double learning_rate{5e-3};  // Adam
  int64_t lr_step_epochs{20};  // StepLR period
  double lr_gamma{0.5};
  double val_fraction{0.2};   // of the training file, split by sample seed
  double loss_weight_z{1.0};  // z in cm
  double loss_weight_cos{5.0};
  double loss_weight_sin{5.0};
  // Weight of the uncertainty loss: Gaussian NLL of z (cm) plus von Mises NLL of theta around
  // the detached point estimate, learned by a second head on the detached CLS token. 0 builds
  // no uncertainty head: the paper's network, point estimates only. Only that head learns from
  // this term, and Adam ignores a constant gradient scale, so any positive value trains alike.
  double uncertainty_weight{1.0};
  bool augment{true};             // time shift + time/frequency masking (train only)
  int64_t time_shift_frames{34};  // +- mel frames, applied to every time-aligned input
  int64_t time_mask_frames{40};
  int64_t freq_mask_bands{5};
  // Flip the sign of every channel of a record at random (half the records, every epoch): a
  // model that must not depend on the wiring's polarity of the discs (waveform features only;
  // a mel image has no sign). Drawn after the other augmentations, so that off changes nothing.
  bool polarity_flip{false};
  // Stretch each record's waveform in time about the window's centre (the onset) by a factor
  // drawn log-uniformly in [1 / (1 + r), 1 + r], r = time_stretch (linear interpolation): every
  // inter-channel delay and the coda scale alike, as a slower or faster group speed would make
  // them, so that no one theory's wave speed is learned as fact. 0: off. Waveform features only;
  // drawn after polarity, so that off changes nothing.
  double time_stretch{0.0};
  // Rotate each record about the tube's axis by a random multiple of 120 degrees (a third of
  // the records each): in both rings of three discs the channels move one disc on and the
  // label's theta by as much. Exact for a tube with the symmetry of its discs, so that no
  // structure's seam or bolt position is learned as the way to the angle. Needs the channels to
  // be rings of three discs 120 degrees apart in order, every ring at the same angles (the
  // experiments layer checks mics.*), and audio alone (a GCC pair or an arm pose would have to
  // rotate too). Drawn after the stretch.
  bool rotate_rings{false};
  // Mirror half the records (drawn after the turn) about disc 0's angle, which must be theta 0:
  // in each ring channels 1 and 2 swap and the label's theta becomes -theta. Exact for a tube
  // with the mirror symmetry of its discs (an ideal tube has it; a seam away from a disc does
  // not). Needs what rotate_rings needs.
  bool mirror_rings{false};
  bool normalize{true};  // per-mic normalization, train-split statistics
  // Save the epoch with the lowest validation loss instead of the last (early stopping without
  // stopping: every epoch still runs). Meant for fine-tuning on few strikes.
  bool keep_best{false};
  // Networks trained (TrainEnsemble), each from its own initialization and augmentation draws
  // on the same split; their predictions are combined (CombinePredictions). 1: one network.
  int64_t ensemble_members{1};
  int64_t threads{0};  // intra-op threads, 0 = all cores

  void Serialize(Archive* a);
  /// Checks every field; throws ConfigError naming the key as "train.<field>".
  void Validate() const;
};

/// In-memory features of N strikes. Row-major flat arrays with the shapes given.
struct FeatureSet {
  int64_t channels{6};
  int64_t mels{50};
  int64_t frames{517};
  int64_t gcc_pairs{15};
  int64_t gcc_lags{883};
  int64_t proprio_rows{50};
  int64_t proprio_features{10};
  // input samples from one audio frame to the next: the mel hop, 1 for a waveform; a time shift
  // of the audio (augmentation) moves the proprioception window by as much time
  int64_t frame_hop_samples{128};
  std::vector<float> mel;         // (N x channels x mels x frames)
  std::vector<float> gcc;         // (N x gcc_pairs x gcc_lags)
  std::vector<float> proprio;     // (N x proprio_rows x proprio_features)
  std::vector<double> z_m;        // (N) labels (may be NaN when unknown)
  std::vector<double> theta_rad;  // (N)
  int64_t size() const { return static_cast<int64_t>(z_m.size()); }
  /// The same shapes with no rows.
  FeatureSet ShapesOnly() const;
  /// Rows `rows` (indices into this set), in that order. An empty array (a modality that is
  /// not used) stays empty; an array of any other size than size() rows is a SchemaError.
  FeatureSet SelectRows(const std::vector<int64_t>& rows) const;
  /// Keeps rows `ascending_rows` (strictly increasing indices) in place, packed to the front of
  /// the same arrays: no second copy of the set, for sets near the size of memory. The arrays
  /// keep their capacity. The same SchemaError as SelectRows.
  void KeepRows(const std::vector<int64_t>& ascending_rows);
};

/// Localization errors over a set of strikes. The coverage and NLL fields are NaN unless every
/// labelled prediction carries a predictive distribution (Prediction::has_uncertainty).
struct Metrics {
  int64_t n{0};
  double med_cm{0.0};            // mean 3-D distance between surface points, cm
  double height_err_cm{0.0};     // mean |dz|, cm
  double angle_err_deg{0.0};     // mean wrapped |dtheta|, degrees
  double reference_med_cm{0.0};  // published code's mixed-unit MED (z in cm, r in m)
  // Fractions of records whose truth lies in the central 50 % / 90 % predictive interval:
  // Gaussian for z, von Mises for theta.
  double z_coverage_50{std::numeric_limits<double>::quiet_NaN()};
  double z_coverage_90{std::numeric_limits<double>::quiet_NaN()};
  double theta_coverage_50{std::numeric_limits<double>::quiet_NaN()};
  double theta_coverage_90{std::numeric_limits<double>::quiet_NaN()};
  // Mean joint negative log-likelihood of the truth, nats: -log p(z in cm) - log p(theta in rad).
  double nll{std::numeric_limits<double>::quiet_NaN()};
};

/// One prediction: the point estimate and, from a model with an uncertainty head, a predictive
/// distribution z ~ Normal(z_m, z_std_m^2), theta ~ VonMises(theta_rad, theta_kappa).
struct Prediction {
  double z_m{0.0};
  double theta_rad{0.0};
  double z_std_m{std::numeric_limits<double>::quiet_NaN()};      // m; NaN without uncertainty
  double theta_kappa{std::numeric_limits<double>::quiet_NaN()};  // von Mises concentration
  bool has_uncertainty() const { return z_std_m > 0.0 && theta_kappa > 0.0; }
};

/// Post-hoc scales of the predictive distribution, fitted on the validation split after
/// training and stored in model.json: z_std_m is multiplied by z_std_scale and theta_kappa by
/// kappa_scale.
struct UncertaintyCalibration {
  // every scale a fit returns, a run stores or a file may hold lies within these
  static constexpr double kMinScale = 1e-4, kMaxScale = 1e4;
  double z_std_scale{1.0};
  double kappa_scale{1.0};
};

/// The scales that minimize the mean NLL of the labelled records of `truth` under `predictions`
/// (records without uncertainty or label are skipped; with none left both scales are 1). The
/// z scale is closed form, s^2 = mean((dz / z_std)^2); the kappa scale is the root of the
/// (monotone) NLL derivative, found by bisection on its logarithm within [1e-4, 1e4].
UncertaintyCalibration FitUncertaintyCalibration(const std::vector<Prediction>& predictions,
                                                 const FeatureSet& truth);
/// `p` with the scales applied (nothing changes for a prediction without uncertainty).
Prediction ApplyCalibration(const Prediction& p, const UncertaintyCalibration& calibration);

/// One prediction from the predictions of an ensemble's members (each calibrated) for the same
/// strike, as a mixture with equal weights: z is the mean of the members' z, z_std the mixture's
/// standard deviation (sqrt of the mean variance plus the variance of the means); theta and
/// theta_kappa match the mixture's first circular moment, the mean of A(kappa_k) exp(i theta_k)
/// with A = I1 / I0 (theta its direction, A(theta_kappa) its length). Members without
/// uncertainty give the circular mean of theta and no distribution. `members` is not empty.
Prediction CombinePredictions(const std::vector<Prediction>& members);
/// The kappa >= 0 with I1(kappa) / I0(kappa) = r, for r in [0, 1) (bisection on log kappa;
/// r = 0 gives 0, r -> 1 large kappa).
double VonMisesKappaForResultant(double r);

/// Half width, in standard deviations, of the central interval of a normal distribution that
/// holds `probability` (0.6745 for 0.5, 1.6449 for 0.9). `probability` in (0, 1).
double GaussianIntervalHalfWidth(double probability);
/// Probability that a von Mises variable with concentration `kappa` (>= 0) lies within
/// `half_width` (>= 0, radians) of its mean, by Gauss-Legendre integration of the density.
double VonMisesCentralProbability(double kappa, double half_width);
/// Half width h in radians of the central interval [mu - h, mu + h] of a von Mises distribution
/// with concentration `kappa` (>= 0) that holds `probability` in (0, 1): the inverse of
/// VonMisesCentralProbability, by Newton's method. kappa -> 0 gives probability * pi (that
/// fraction of the circle); large kappa approaches the normal value
/// GaussianIntervalHalfWidth(probability) / sqrt(kappa).
double VonMisesIntervalHalfWidth(double kappa, double probability);
/// Circular standard deviation sqrt(-2 ln(I1(kappa) / I0(kappa))) in radians: about
/// 1 / sqrt(kappa) for large kappa, unbounded as kappa -> 0.
double VonMisesCircularStd(double kappa);
/// log I0(kappa), stable for every kappa >= 0.
double LogBesselI0(double kappa);

/// This process's place among the processes of one data-parallel training (Train), as the usual
/// launcher variables give it: RANK, WORLD_SIZE, MASTER_ADDR, MASTER_PORT (torchrun's; srun and
/// mpirun set them through scripts/cluster/train_ddp.sh). Rank 0 hosts the rendezvous (a c10d
/// TCPStore at master_addr:master_port) that the others join within timeout_s.
struct DataParallel {
  int rank{0};
  int world_size{1};
  std::string master_addr{"127.0.0.1"};
  int master_port{29500};
  double timeout_s{1800.0};  // rendezvous and collectives (rank 0 may still be reading features)

  /// From the environment; world_size 1 when WORLD_SIZE is unset. ConfigError naming the
  /// variable for a value that is not an integer or lies outside its range.
  static DataParallel FromEnvironment();
};

/// Fine-tuning: start from a trained run's weights instead of a fresh initialization.
struct FineTune {
  enum class Freeze {
    kNone,        // every weight trains
    kEncoders,    // the modality encoders stay as pretrained (their BatchNorm statistics too)
    kAllButHead,  // only the output heads (point and uncertainty) train
  };
  std::string init_from;  // run directory; empty: train from scratch
  Freeze freeze{Freeze::kNone};
  bool refit_normalization{false};  // false: keep the pretrained per-mic mel statistics;
                                    // true: recompute them on the target's training split
  // The interval scales after training: fitted on the validation split (FitOrKeepCalibration), or
  // the pretrained run's kept whatever its size (the validation split then informs nothing).
  enum class Calibration { kFitOnValidation, kKeepPretrained };
  Calibration calibration{Calibration::kFitOnValidation};
};
inline constexpr EnumName<FineTune::Freeze> kFreezeNames[] = {
    {FineTune::Freeze::kNone, "none"},
    {FineTune::Freeze::kEncoders, "encoders"},
    {FineTune::Freeze::kAllButHead, "all-but-head"}};
inline std::span<const EnumName<FineTune::Freeze>> EnumNames(FineTune::Freeze) {
  return kFreezeNames;
}

/// Trains on `train`, validates on `val` each epoch, writes into run_dir:
/// model.pt (weights + normalization), model.json (ModelConfig + shapes + tube radius +
/// uncertainty calibration), metrics.jsonl (one line per epoch, uncalibrated uncertainty),
/// checkpoint.pt (resume: weights, Adam's state and the epoch count after every epoch; once the
/// run is finished, without the weights, which are model.pt's). Resumes from
/// run_dir/checkpoint.pt when it exists and `resume` is set. After the last epoch the predictive
/// distribution is calibrated on `val` (FitOrKeepCalibration: with fewer than kMinFitRecords
/// usable strikes, a fine-tune keeps its pretrained scales and a fresh run scales 1).
/// `surface_radius_m` is used for the 3-D metrics.
/// Returns the validation metrics of the final, calibrated model. With `fine_tune.init_from`
/// the network starts from that run's model.pt (same model config and feature shapes, else
/// SchemaError naming the file), frozen and normalized as `fine_tune` says; the calibration is
/// refitted on `val` as always (or the pretrained scales kept, as above).
/// Process-wide side effects, kept after it returns: torch's intra-op thread count
/// (train_config.threads) and, with glibc, malloc settings that keep freed memory for reuse
/// (resident memory stays near its peak; see PrepareTrainingProcess in internal/train_step.h).
///
/// Data parallel (parallel.world_size > 1): every process calls Train with the same features and
/// configs; each global batch of train.batch_size records is split in contiguous parts, one per
/// process, whose gradients are summed (weighted by their share of the batch) over c10d's Gloo
/// backend before each optimizer step, so the processes keep identical weights and the step is
/// the one-process step of the whole batch (BatchNorm sees each part's statistics; its running
/// statistics are averaged after every epoch). Rank 0 validates and writes the run; the others
/// write nothing and return empty metrics.
Metrics Train(const FeatureSet& train, const FeatureSet& val, const ModelConfig& model_config,
              const TrainConfig& train_config, double surface_radius_m, uint64_t seed,
              const std::string& run_dir, bool resume, bool show_progress,
              const FineTune& fine_tune = {}, const DataParallel& parallel = {});

/// Trains train_config.ensemble_members networks with Train. One member: Train itself, the run
/// directory as it writes it. More: member k in run_dir/member<k> (seed: `seed` for member 0,
/// SampleSeed(seed, k) for the others; the same train and val sets), then run_dir/ensemble.json
/// naming them, with the calibration of their combination fitted on `val`; Localizer loads the
/// directory as one model. Returns the metrics of the calibrated combined predictions on `val`. A
/// fine-tune of an ensemble (fine_tune.init_from an ensemble directory) fine-tunes member k from
/// the pretrained member k; the member counts must agree (ConfigError naming
/// train.ensemble_members).
Metrics TrainEnsemble(const FeatureSet& train, const FeatureSet& val,
                      const ModelConfig& model_config, const TrainConfig& train_config,
                      double surface_radius_m, uint64_t seed, const std::string& run_dir,
                      bool resume, bool show_progress, const FineTune& fine_tune = {},
                      const DataParallel& parallel = {});

/// Member run directories of an ensemble directory (its ensemble.json), in order; empty for a
/// plain run directory. SchemaError naming the file when ensemble.json is malformed.
std::vector<std::string> EnsembleMembers(const std::string& run_dir);
/// The scales of an ensemble's combined distribution, fitted on the validation split after its
/// members were trained (ensemble.json "uncertainty"; 1 and 1 when absent). SchemaError naming
/// the file for a scale that is not a positive number.
UncertaintyCalibration EnsembleCalibration(const std::string& run_dir);

/// The fewest strikes any statistic fitted from data rests on: the interval scales (calibrate,
/// and the calibration inside train, fine-tunes and pseudo-label runs) and adapted statistics
/// (adapt). A scale fitted on n strikes has a relative standard error near 1 / sqrt(2 n): 13 %
/// at 30, 41 % at 3 (train fitted sigma_z x 0.04 and kappa x 0.0001 on 1-2 strikes).
inline constexpr int64_t kMinFitRecords = 30;

/// Labelled records with a predictive distribution: those a calibration fit can use.
int64_t CalibrationRecords(const std::vector<Prediction>& predictions, const FeatureSet& truth);

/// The scales a training stores: fitted on its validation split (FitUncertaintyCalibration)
/// when at least kMinFitRecords records can be used; otherwise `kept` (the pretrained run's
/// scales in a fine-tune, 1 and 1 from scratch), with a warning naming `kept_what`.
struct CalibrationFit {
  UncertaintyCalibration scales;
  int64_t records{0};  // usable records (CalibrationRecords)
  bool fitted{false};
  std::string method;  // how the scales came about, as model.json's "uncertainty" says it
};
CalibrationFit FitOrKeepCalibration(const std::vector<Prediction>& predictions,
                                    const FeatureSet& truth, const UncertaintyCalibration& kept,
                                    const std::string& kept_what);

/// `kept` unfitted (FineTune::Calibration::kKeepPretrained), its method naming `kept_what`.
CalibrationFit KeptCalibrationFit(const UncertaintyCalibration& kept, const std::string& kept_what);

/// A finished run's calibration refitted on other labelled records (`sonicboom calibrate`).
struct Recalibration {
  UncertaintyCalibration before;    // stored in the run until now
  UncertaintyCalibration relative;  // fitted on the records, on top of `before` (as applied:
                                    // after / before once `after` is bounded)
  UncertaintyCalibration after;     // stored now: before x relative, scale by scale
};
/// Fits the scales (by `fit`) of `truth` under `predictions` (the run's own
/// calibrated predictions of those records, Localizer(run_dir).Predict), multiplies them into
/// the run's stored scales (model.json, or ensemble.json for an ensemble; written atomically)
/// and records `source` and the record count beside them (a file without scales, written
/// before calibration existed, counts as scales 1). Later `train --resume` of the run refits on
/// its validation split again. The stored scales stay within UncertaintyCalibration's bounds
/// (repeated refits on few strikes drove kappa to 1e-32). SchemaError naming the file when fewer
/// than kMinFitRecords labelled records carry a predictive distribution, or predictions and
/// labels differ in number.
/// How Recalibrate fits: the scales minimizing the mean NLL (FitUncertaintyCalibration), or
/// those under which 90 % of the records fall inside their 90 % intervals (FitCoverageCalibration,
/// conformal.h: the honest choice on a family harder than the training's, whose errors are
/// heavy-tailed).
enum class IntervalFit { kLikelihood, kCoverage };
inline constexpr EnumName<IntervalFit> kIntervalFitNames[] = {
    {IntervalFit::kLikelihood, "likelihood"}, {IntervalFit::kCoverage, "coverage"}};
inline std::span<const EnumName<IntervalFit>> EnumNames(IntervalFit) {
  return kIntervalFitNames;
}
Recalibration Recalibrate(const std::string& run_dir, const std::vector<Prediction>& predictions,
                          const FeatureSet& truth, const std::string& source,
                          IntervalFit fit = IntervalFit::kLikelihood);

/// Unlabelled adaptation (`sonicboom adapt`): a trained run's statistics of its inputs and
/// hidden layers re-estimated on strikes of another structure, labels unread. The weights stay;
/// what a layer takes as its typical input becomes the target's (for BatchNorm, the "AdaBN"
/// idea). The interval scales stay those of the source's validation split.
struct AdaptOptions {
  bool batch_norm{true};      // every BatchNorm layer's running mean and variance, re-estimated
                              // as the plain average over the target's records (in eval mode
                              // otherwise: no dropout)
  bool mel_statistics{true};  // the per-mic input mean and std (train.normalize), refitted first
};
struct AdaptReport {
  int64_t records{0};            // target strikes read
  int64_t members{0};            // networks adapted (an ensemble's all)
  int64_t batch_norm_layers{0};  // per network
};
/// Adapts run_dir (a run or an ensemble directory) to `target` and writes the result to out_dir
/// as a run of the same layout (model.json gains "adapted": source, records, options); out_dir
/// must not exist or be empty (so it is never run_dir). The files that mark a run complete
/// (model.json, ensemble.json) are written last. Throws ConfigError for a target of fewer than
/// kMinFitRecords strikes or out_dir in use, SchemaError for features of other shapes.
AdaptReport AdaptToUnlabelled(const std::string& run_dir, const FeatureSet& target,
                              const std::string& out_dir, const AdaptOptions& options);

/// First frame of the network's centre crop of `crop_frames` frames in a `frames`-frame mel
/// spectrogram (the un-augmented crop of training, evaluation and localization).
int64_t CentreCropStart(int64_t frames, int64_t crop_frames);

/// What a model reads of each strike's features: its modalities and, with audio, the frames of
/// its centre crop in the whole-window spectrogram. A feature set holding only those frames
/// (FeatureSet.frames == mel_frames) is taken by Localizer::Predict as the crop itself.
struct FeatureNeeds {
  bool audio{true};
  bool gcc{true};
  bool proprio{true};
  int64_t mel_first_frame{0};
  int64_t mel_frames{0};
};

/// A trained model loaded from a run directory, for evaluation and localization; from an
/// ensemble directory (TrainEnsemble), every member, whose predictions are combined
/// (CombinePredictions). Members must read the same features.
/// How a Localizer answers.
struct LocalizerOptions {
  /// Each strike read as it is and turned by 120 and 240 degrees (each ring of three discs
  /// moved one and two discs on), every answer turned back, and the three combined as the
  /// members of an ensemble are (CombinePredictions): a network that should not have learned one
  /// disc position from another (train.rotate_rings) answers by the symmetry of the layout.
  /// Needs model.modalities = [audio] and channels in rings of three (ConfigError otherwise).
  /// On whenever the run's model.turn_average is.
  bool turn_average{false};
  /// With turn_average: each turn also read mirrored about theta 0 (in each ring discs 1 and 2
  /// swapped, the answer's theta negated back), six answers combined: the discs' mirror symmetry
  /// (train.mirror_rings). On whenever the run's model.mirror_average is.
  bool mirror_average{false};
};

class Localizer {
 public:
  /// Throws IoError/SchemaError naming the file.
  explicit Localizer(const std::string& run_dir, const LocalizerOptions& options = {});
  ~Localizer();
  Localizer(Localizer&&) noexcept;
  Localizer& operator=(Localizer&&) noexcept;

  /// Point estimates and, when the model has an uncertainty head, the calibrated predictive
  /// distribution (see Prediction). `features` holds the whole-window spectrogram (as trained)
  /// or only the crop (needs()); arrays of modalities the model does not read may be empty.
  std::vector<Prediction> Predict(const FeatureSet& features) const;
  /// The features the model reads (for featurizers that compute only those).
  FeatureNeeds needs() const;
  /// Whether predictions carry a distribution: false for models trained with
  /// train.uncertainty_weight = 0 or before the uncertainty head existed (their weights lack it).
  bool has_uncertainty() const;
  /// The scales from model.json (1 and 1 when the file predates calibration); an ensemble's
  /// from ensemble.json, applied to the combined distribution.
  const UncertaintyCalibration& calibration() const;
  const ModelConfig& model_config() const;
  double surface_radius_m() const;
  /// Trainable parameters of the loaded network per part (see CountParameters), summed over
  /// the members of an ensemble.
  std::map<std::string, int64_t> ParameterCounts() const;
  /// Networks combined: 1, or an ensemble's member count.
  int64_t members() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Trainable parameters of the network that `config` builds for features shaped like `shapes`
/// (only the shape fields are read), per part: "audio_encoder", "gcc_encoder", "proprio_encoder"
/// (present only when the modality is selected) and "fusion" (tokens, transformer, heads;
/// with `uncertainty_head` the network of a training with train.uncertainty_weight > 0).
std::map<std::string, int64_t> CountParameters(const ModelConfig& config, const FeatureSet& shapes,
                                               bool uncertainty_head = true);

/// Distance in cm between the surface points (r cos theta, r sin theta, z) of a prediction and
/// of the label (z_m, theta_rad) on a tube of `surface_radius_m`: one strike's term of the MED.
double SurfaceErrorCm(const Prediction& p, double z_m, double theta_rad, double surface_radius_m);

/// Metrics of predictions against the labels in `truth`; coverage and NLL when every labelled
/// prediction has uncertainty.
Metrics ComputeMetrics(const std::vector<Prediction>& predictions, const FeatureSet& truth,
                       double surface_radius_m);

}  // namespace sonicboom::learning
