// The bad-input matrix: every case runs the CLI on a damaged or hostile input and asserts a
// non-zero exit, a message naming the file, key or value, and that no existing file changed.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "common/test_util.h"
#include "common/workspace.h"

namespace sonicboom::experiments {
namespace {

namespace fs = std::filesystem;
using sonicboom::testing::CliRun;
using sonicboom::testing::kShortRecordArgs;
using sonicboom::testing::kTinyModelArgs;
using sonicboom::testing::ReadBytes;
using sonicboom::testing::RunCli;
using sonicboom::testing::Snapshot;
using sonicboom::testing::TempDir;

// A float WAV of (frames x channels) values, written byte by byte (the project's writer refuses
// what these tests need: non-finite and out-of-range samples).
void WriteRawFloatWav(const fs::path& path, const std::vector<float>& interleaved, int channels,
                      int rate = 44100) {
  std::ofstream out(path, std::ios::binary);
  auto u32 = [&](uint32_t v) { out.write(reinterpret_cast<const char*>(&v), 4); };
  auto u16 = [&](uint16_t v) { out.write(reinterpret_cast<const char*>(&v), 2); };
  const uint32_t bytes = static_cast<uint32_t>(interleaved.size() * sizeof(float));
  out.write("RIFF", 4);
  u32(36 + bytes);
  out.write("WAVEfmt ", 8);
  u32(16);
  u16(3);  // IEEE float
  u16(static_cast<uint16_t>(channels));
  u32(static_cast<uint32_t>(rate));
  u32(static_cast<uint32_t>(rate * channels * 4));
  u16(static_cast<uint16_t>(channels * 4));
  u16(32);
  out.write("data", 4);
  u32(bytes);
  out.write(reinterpret_cast<const char*>(interleaved.data()), bytes);
}

// 0.6 s of six channels: low noise and a burst at 0.25 s (what a strike record looks like)
std::vector<float> StrikeLikeRecord(int frames = 26460, int channels = 6) {
  std::vector<float> x(static_cast<size_t>(frames) * channels);
  uint32_t state = 12345;
  for (size_t i = 0; i < x.size(); ++i) {
    state = state * 1664525u + 1013904223u;
    x[i] = 0.01f * (static_cast<float>(state >> 8) / 16777216.0f - 0.5f);
  }
  for (int t = 11025; t < std::min(frames, 11100); ++t) {
    for (int c = 0; c < channels; ++c) x[static_cast<size_t>(t) * channels + c] += 0.5f;
  }
  return x;
}

// Copies of D.h5 damaged with h5py: z as int32 millimetres, z as float millimetres, a NaN in the
// proprioception, a repeated sample index, an infinite angle, 1000-frame records, and the
// `complete` mark removed.
void MakeDamagedDatasets(const fs::path& dir) {
  std::ofstream(dir / "damage.py") << R"(import shutil, sys, h5py, numpy as np
def variant(name, fn):
    shutil.copy('D.h5', name)
    with h5py.File(name, 'r+') as f: fn(f)
def z_int_mm(f):
    z = f['label/z_m'][:]; del f['label/z_m']
    f.create_dataset('label/z_m', data=np.round(z * 1000).astype('int32'), maxshape=(None,), chunks=True)
def z_float_mm(f): f['label/z_m'][:] = f['label/z_m'][:] * 1000
def nan_proprio(f):
    p = f['proprio'][:]; p[3, 5, 2] = np.nan; f['proprio'][:] = p
def repeated_index(f):
    i = f['index/sample_index'][:]; i[5] = i[4]; f['index/sample_index'][:] = i
def inf_theta(f):
    t = f['label/theta_rad'][:]; t[1] = np.inf; f['label/theta_rad'][:] = t
def short_records(f):
    a = f['audio'][:, :, :1000]; scale = f['audio'].attrs['scale']; del f['audio']
    d = f.create_dataset('audio', data=a, chunks=(1, a.shape[1], 1000)); d.attrs['scale'] = scale
def incomplete(f): del f.attrs['complete']
for name, fn in [('ZINT.h5', z_int_mm), ('ZMM.h5', z_float_mm), ('NANP.h5', nan_proprio),
                 ('DUP.h5', repeated_index), ('INF.h5', inf_theta), ('SHORT.h5', short_records),
                 ('PART.h5', incomplete)]:
    variant(name, fn)
)";
  const CliRun run =
      sonicboom::testing::RunProgram({"/usr/bin/python3", "damage.py"}, dir.string());
  ASSERT_EQ(run.exit_code, 0) << run.err;
}

// The suite's workspace: a short-record dataset, a tiny trained run, a strike WAV, a robot log,
// shards, and the damaged inputs made from them.
void BuildWorkspace(const fs::path& dir) {
  std::vector<std::string> commands = {
      kShortRecordArgs + "-q generate --count 24 --out D.h5",
      kShortRecordArgs + kTinyModelArgs + "--set train.epochs=1 -q train --data D.h5 --out RUN",
      kShortRecordArgs + "-q synth --out X.wav", "-q export --layout trial --in D.h5 --out TR"};
  for (int s = 0; s < 2; ++s) {
    commands.push_back(kShortRecordArgs + "-q generate --count 8 --shard " + std::to_string(s) +
                       " --num-shards 2 --out S" + std::to_string(s) + ".h5");
  }
  commands.push_back(kShortRecordArgs +
                     "-q generate --count 6 --shard 1 --num-shards 2 --out T1.h5");
  sonicboom::testing::RunEach(commands, dir);
  if (::testing::Test::HasFatalFailure()) return;
  std::ofstream(dir / "P.csv")
      << "t_s,x_m,y_m,z_m,qw,qx,qy,qz,vx_m_s,vy_m_s,vz_m_s\n0,0.5,0,0.5,1,0,0,0,0,0,0\n";
  MakeDamagedDatasets(dir);
}

constexpr sonicboom::testing::Workspace kWorkspace{"hostile_input", BuildWorkspace};

// Built once per ctest run (the suite's fixture) for its tests to copy
TEST(HostileInputWorkspace, IsBuilt) {
  sonicboom::testing::PublishWorkspace(kWorkspace);
}

// Each test process works in its own copy of the workspace
class HostileInputTest : public sonicboom::testing::WorkspaceTest<kWorkspace> {
 protected:
  // Runs `args`; expects exit `exit_code` (any non-zero when 0 is passed), every substring in
  // stderr, and no file of the workspace changed or added (but files the case names in `new_ok`).
  static void ExpectRefused(const std::string& args, const std::vector<std::string>& substrings,
                            int exit_code = 0) {
    const std::map<std::string, std::string> before = Snapshot(dir_->path());
    const CliRun run = RunCli(args, dir_->path().string());
    if (exit_code == 0) {
      EXPECT_NE(run.exit_code, 0) << args << "\n" << run.out;
    } else {
      EXPECT_EQ(run.exit_code, exit_code) << args << "\n" << run.err;
    }
    for (const std::string& s : substrings) {
      EXPECT_NE(run.err.find(s), std::string::npos) << args << "\nmissing '" << s << "' in:\n"
                                                    << run.err;
    }
    // 'internal error', a signal or an abort is never the answer to bad input
    EXPECT_EQ(run.err.find("internal error"), std::string::npos) << args << "\n" << run.err;
    EXPECT_TRUE(run.exit_code == 1 || run.exit_code == 2) << args << ": exit " << run.exit_code;
    const std::map<std::string, std::string> after = Snapshot(dir_->path());
    for (const auto& [path, bytes] : before) {
      const auto it = after.find(path);
      ASSERT_NE(it, after.end()) << args << " removed " << path;
      EXPECT_TRUE(it->second == bytes) << args << " changed " << path;
    }
    for (const auto& [path, bytes] : after) {
      EXPECT_TRUE(before.count(path) == 1 || path.ends_with(".stderr.txt"))
          << args << " left " << path;
    }
  }

  static fs::path Path(const std::string& name) { return dir_->path() / name; }
};

TEST_F(HostileInputTest, WavRecordsAreRefusedNamingFileFrameAndChannel) {
  const std::vector<float> good = StrikeLikeRecord();
  auto with = [&](const std::string& name, const std::vector<float>& x, int channels = 6,
                  int rate = 44100) { WriteRawFloatWav(Path(name), x, channels, rate); };
  std::vector<float> x = good;
  x[5000 * 6 + 2] = std::nanf("");
  with("nan.wav", x);
  x = good;
  x[6000 * 6 + 1] = INFINITY;
  with("inf.wav", x);
  x = good;
  for (float& v : x) v *= 1e6f;
  with("volts.wav", x);
  with("zero.wav", std::vector<float>(good.size(), 0.0f));
  with("short.wav", std::vector<float>(good.begin(), good.begin() + 4410 * 6));
  with("one.wav", std::vector<float>(good.begin(), good.begin() + 6));
  with("four.wav", StrikeLikeRecord(26460, 4), 4);
  with("rate.wav", good, 6, 48000);
  std::ofstream(Path("text.wav")) << "not a sound file\n";
  const std::string localize = kShortRecordArgs + "localize --model RUN --wav ";
  for (const char* gating : {"", "--set features.gating=false "}) {
    ExpectRefused(gating + localize + "nan.wav", {"nan.wav: frame 5000", "channel 2 is nan"}, 1);
    ExpectRefused(gating + localize + "inf.wav", {"inf.wav: frame 6000", "channel 1 is inf"}, 1);
  }
  ExpectRefused(localize + "volts.wav", {"volts.wav", "beyond full scale"}, 1);
  ExpectRefused(localize + "zero.wav", {"zero.wav: channel 0 is silent"}, 1);
  ExpectRefused(localize + "short.wav", {"short.wav: 4410 frames", "shorter than"}, 1);
  ExpectRefused(localize + "one.wav", {"one.wav: 1 frames", "shorter than"}, 1);
  ExpectRefused(localize + "four.wav", {"four.wav: expected 6 channels, found 4"}, 1);
  ExpectRefused(localize + "rate.wav", {"rate.wav: sample rate 48000 Hz"}, 1);
  ExpectRefused(localize + "text.wav", {"text.wav"}, 1);
  ExpectRefused(kShortRecordArgs + "features --in nan.wav --out F.h5", {"nan.wav: frame 5000"}, 1);
  ExpectRefused(kShortRecordArgs + "localize --method arrival --wav zero.wav",
                {"zero.wav: channel 0 is silent"}, 1);
  // records with no strike in them: noise alone, a constant level, a burst in the last 2 ms
  std::vector<float> noise = good;
  for (int t = 11025; t < 11100; ++t) {
    for (int c = 0; c < 6; ++c) noise[static_cast<size_t>(t) * 6 + c] -= 0.5f;
  }
  with("noise.wav", noise);
  with("dc.wav", std::vector<float>(good.size(), 0.2f));
  std::vector<float> late = noise;
  for (int t = 26380; t < 26460; ++t) {
    for (int c = 0; c < 6; ++c) late[static_cast<size_t>(t) * 6 + c] += 0.5f;
  }
  with("late.wav", late);
  for (const std::string& method : {std::string("--model RUN"), std::string("--method arrival")}) {
    const std::string run = kShortRecordArgs + "localize " + method + " --wav ";
    ExpectRefused(run + "noise.wav", {"noise.wav: no strike found", "dB above"}, 1);
    ExpectRefused(run + "dc.wav", {"dc.wav: no strike found"}, 1);
    ExpectRefused(run + "late.wav", {"late.wav: no strike found", "before the record's end"}, 1);
  }
}

TEST_F(HostileInputTest, RobotLogsAreRefusedNamingLineAndColumn) {
  const std::string header = "t_s,x_m,y_m,z_m,qw,qx,qy,qz,vx_m_s,vy_m_s,vz_m_s\n";
  const std::string row0 = "0,0.5,0,0.5,1,0,0,0,0,0,0\n";
  std::ofstream(Path("far.csv")) << header << row0 << "0.01,1e30,0,0.5,1,0,0,0,0,0,0\n";
  std::ofstream(Path("nan.csv")) << header << row0 << "0.01,0.5,nan,0.5,1,0,0,0,0,0,0\n";
  std::ofstream(Path("back.csv")) << header << row0 << "0,0.5,0,0.5,1,0,0,0,0,0,0\n";
  std::ofstream(Path("quat.csv")) << header << "0,0.5,0,0.5,2,0,0,0,0,0,0\n";
  std::ofstream(Path("fast.csv")) << header << "0,0.5,0,0.5,1,0,0,0,300,0,0\n";
  std::ofstream(Path("head.csv")) << "t,x,y,z\n" << row0;
  const std::string localize = kShortRecordArgs + "localize --model RUN --wav X.wav --proprio ";
  ExpectRefused(localize + "far.csv", {"far.csv:3", "from the robot base"}, 1);
  ExpectRefused(localize + "nan.csv", {"nan.csv:3", "column 3 is not finite"}, 1);
  ExpectRefused(localize + "back.csv", {"back.csv:3", "does not follow"}, 1);
  ExpectRefused(localize + "quat.csv", {"quat.csv:2", "quaternion"}, 1);
  ExpectRefused(localize + "fast.csv", {"fast.csv:2", "m/s"}, 1);
  ExpectRefused(localize + "head.csv", {"head.csv:1", "expected header"}, 1);
}

TEST_F(HostileInputTest, DamagedDatasetsAreRefusedByEveryReader) {
  const std::vector<std::pair<std::string, std::vector<std::string>>> cases = {
      {"ZINT.h5", {"ZINT.h5: /label/z_m is int32", "floating point"}},
      {"ZMM.h5", {"ZMM.h5: sample row 0", "off the tube"}},
      {"NANP.h5", {"NANP.h5: /proprio of sample row 3", "non-finite"}},
      {"DUP.h5", {"DUP.h5: sample index 4 appears twice"}},
      {"INF.h5", {"INF.h5: /label/theta_rad of sample row 1 is infinite"}},
      {"SHORT.h5", {"SHORT.h5: records of 1000 frames"}},
      {"PART.h5", {"PART.h5: incomplete dataset"}}};
  for (const auto& [file, messages] : cases) {
    ExpectRefused(kShortRecordArgs + "eval --model RUN --data " + file, messages, 1);
    ExpectRefused(kShortRecordArgs + kTinyModelArgs + "train --data " + file + " --out R2",
                  messages, 1);
  }
  // features and the baselines read through the same checks
  ExpectRefused(kShortRecordArgs + "features --in ZMM.h5 --out F.h5", {"off the tube"}, 1);
  ExpectRefused(kShortRecordArgs + "baseline --method arrival --data NANP.h5", {"NANP.h5"}, 1);
  std::ofstream(Path("notes.h5")) << "not hdf5";
  ExpectRefused("eval --model RUN --data notes.h5", {"notes.h5"}, 1);
}

// Files found by fuzz/dataset_fuzz.cc on which libhdf5 1.10 loops for ever, or over-reads a
// damaged global heap until the process faults: the readers' deadline and fault guard turn the
// hang and the crash into an error naming the file, and nothing is written.
TEST_F(HostileInputTest, FilesLibhdf5FailsOnEndInAnErrorNotAHangOrACrash) {
  const fs::path hostile = fs::path(SONICBOOM_SOURCE_DIR) / "tests/data/hostile";
  fs::copy_file(hostile / "hdf5_heap_loop.h5", Path("LOOP.h5"));
  fs::copy_file(hostile / "hdf5_heap_overread.h5", Path("OVER.h5"));
  // yaml-cpp's LoadAll never ends on this config (fuzzing): at most two documents are parsed
  ExpectRefused("--config " + (hostile / "yaml_loadall_loop.yaml").string() + " config",
                {"yaml_loadall_loop.yaml: holds more than one YAML document"}, 1);
  setenv("SONICBOOM_READ_TIMEOUT_S", "2", 1);
  ExpectRefused("inspect LOOP.h5", {"LOOP.h5: reading", "does not finish", "corrupted"}, 1);
  ExpectRefused(kShortRecordArgs + "eval --model RUN --data LOOP.h5",
                {"LOOP.h5", "does not finish"}, 1);
  // a deadline that is not plain seconds is refused, not read as "none" (it hung) or as one
  // that overflowed the clock (1e30 fired at once)
  for (const char* bad : {"abc", "-1", "1e30", "0x10", "nan"}) {
    setenv("SONICBOOM_READ_TIMEOUT_S", bad, 1);
    ExpectRefused("inspect LOOP.h5", {"SONICBOOM_READ_TIMEOUT_S", bad}, 1);
  }
  unsetenv("SONICBOOM_READ_TIMEOUT_S");
  ExpectRefused("inspect OVER.h5", {"OVER.h5: reading the file crashed", "corrupted"}, 1);
  ExpectRefused(kShortRecordArgs + "eval --model RUN --data OVER.h5", {"OVER.h5", "crashed"}, 1);
  ExpectRefused(kShortRecordArgs + kTinyModelArgs + "train --data OVER.h5 --out R3",
                {"OVER.h5", "crashed"}, 1);
  ExpectRefused("merge --out M.h5 OVER.h5 S0.h5", {"OVER.h5", "crashed"}, 1);
}

TEST_F(HostileInputTest, ConfigFilesAndValuesAreRefusedNamingTheKey) {
  std::ofstream(Path("alias.yaml")) << "tube: &t\n  length_m: 0.3\n  self: *t\n";
  std::ofstream(Path("twice.yaml")) << "tube:\n  length_m: 0.3\n  length_m: 0.4\n";
  std::ofstream(Path("mode.yaml")) << "scene:\n  mode: walk\n";
  std::ofstream(Path("unknown.yaml")) << "tube:\n  lenght_m: 0.3\n";
  std::ofstream(Path("rate.yaml")) << "audio:\n  sample_rate_hz: 10\n";
  fs::create_directories(Path("confdir"));
  ExpectRefused("--config alias.yaml config", {"nests deeper"}, 1);
  ExpectRefused("--config twice.yaml config", {"tube.length_m", "appears twice"}, 1);
  ExpectRefused("--config mode.yaml config", {"scene.mode", "strike, stationary, guided"}, 1);
  ExpectRefused("--config unknown.yaml config", {"tube.lenght_m"}, 1);
  ExpectRefused("--config rate.yaml config", {"audio.sample_rate_hz", "rate.yaml"}, 1);
  ExpectRefused("--config confdir config", {"confdir: is a directory"}, 1);
  ExpectRefused("--set strike.engine=warp config", {"strike.engine", "mujoco, kinematic"}, 1);
}

TEST_F(HostileInputTest, CliValuesOutsideTheirLimitsNameTheOption) {
  ExpectRefused(kShortRecordArgs + "generate --count 0 --out G.h5", {"--count"}, 1);
  ExpectRefused(kShortRecordArgs + "generate --count -1 --out G.h5", {"--count"}, 1);
  ExpectRefused(kShortRecordArgs + "generate --first-index -1 --out G.h5", {"--first-index"}, 1);
  ExpectRefused(kShortRecordArgs + "generate --count 4 --shard 4 --num-shards 2 --out G.h5",
                {"--shard"}, 1);
  ExpectRefused(kShortRecordArgs + "generate --count 4 --shard auto --out G-{shard}.h5",
                {"--shard auto", "no launcher variables"}, 1);
  ExpectRefused(kShortRecordArgs + "localize --model RUN --wav X.wav --repeat 0", {"--repeat"}, 1);
  ExpectRefused("baseline --method nearest --data D.h5", {"--method", "knn, tdoa"}, 2);
  ExpectRefused("train --data D.h5 --out R2 --freeze most", {"--freeze", "all-but-head"}, 2);
}

TEST_F(HostileInputTest, OutputsNeverOverwriteInputsOrFinishedWork) {
  // an output that is an input
  ExpectRefused(kShortRecordArgs + "features --in D.h5 --out D.h5", {"is an input"}, 1);
  ExpectRefused(kShortRecordArgs + "features --in X.wav --out X.wav", {"is an input"}, 1);
  ExpectRefused("merge --out S0.h5 S0.h5 S1.h5", {"is an input"}, 1);
  std::ofstream(Path("C.yaml")) << "seed: 3\n";
  ExpectRefused("--config C.yaml generate --count 2 --out C.yaml", {"is an input"}, 1);
  // --force replaces an old output, never an input, an input's sidecar or anything inside a
  // directory the command reads, nor a directory that holds an input
  ExpectRefused("import --layout trial --in TR --out TR/trial0/mic2.wav --force",
                {"lies inside an input (--in TR)"}, 1);
  ExpectRefused("eval --model RUN --data D.h5 --predictions RUN/model.json --force",
                {"lies inside an input (--model RUN)"}, 1);
  ExpectRefused("eval --model RUN --data D.h5 --predictions D.h5.config.yaml --force",
                {"is an input's config sidecar (--data D.h5)"}, 1);
  ExpectRefused(kShortRecordArgs + kTinyModelArgs +
                    "train --data D.h5 --init-from RUN --out RUN/again --force",
                {"lies inside an input (--init-from RUN)"}, 1);
  ExpectRefused(kShortRecordArgs + kTinyModelArgs + "train --data TR/../D.h5 --out . --force",
                {"holds an input (--data TR/../D.h5)"}, 1);
  ExpectRefused("export --layout trial --in D.h5 --out .", {"holds an input (--in D.h5)"}, 1);
  ExpectRefused("listen --model RUN --wav X.wav --save RUN", {"is an input (--model RUN)"}, 1);
  ExpectRefused("listen --model RUN --wav X.wav --save TR", {"TR: is not empty"}, 1);
  // finished outputs need --force
  ExpectRefused(kShortRecordArgs + "synth --out X.wav", {"X.wav: exists; --force"}, 1);
  ExpectRefused(kShortRecordArgs + "synth --out RUN/model.pt", {".wav"}, 1);
  ExpectRefused(kShortRecordArgs + "generate --count 3 --out D.h5",
                {"D.h5: exists and holds another dataset; --force"}, 1);
  ExpectRefused(kShortRecordArgs + kTinyModelArgs + "train --data D.h5 --out RUN",
                {"RUN: exists; --force"}, 1);
  ExpectRefused(kShortRecordArgs + "features --in D.h5 --out nowhere/F.h5",
                {"nowhere", "does not exist"}, 1);
  // a sidecar obeys --force as its output does: one beside no output is someone else's
  std::ofstream(Path("side.h5.config.yaml")) << "# another run's\n";
  std::ofstream(Path("s2.wav.config.yaml")) << "# another run's\n";
  std::ofstream(Path("F.h5.config.yaml")) << "# another run's\n";
  ExpectRefused(kShortRecordArgs + "generate --count 2 --out side.h5",
                {"side.h5.config.yaml: exists (a config sidecar beside no --out side.h5)"}, 1);
  ExpectRefused(kShortRecordArgs + "synth --out s2.wav",
                {"s2.wav.config.yaml: exists", "--force replaces it"}, 1);
  ExpectRefused(kShortRecordArgs + "features --in D.h5 --out F.h5", {"F.h5.config.yaml: exists"},
                1);
  ExpectRefused("merge --out side.h5 S0.h5 S1.h5", {"side.h5.config.yaml: exists"}, 1);
  // inspect --png replaces neither a figure nor its data without --force
  std::ofstream(Path("mine.png")) << "a figure of the user's\n";
  std::ofstream(Path("theirs.png.json")) << "{}\n";
  ExpectRefused("inspect D.h5 --png mine.png", {"mine.png: exists; --force"}, 1);
  ExpectRefused("inspect D.h5 --png theirs.png", {"theirs.png.json: exists; --force"}, 1);
  for (const char* name : {"side.h5.config.yaml", "s2.wav.config.yaml", "F.h5.config.yaml",
                           "mine.png", "theirs.png.json"}) {
    fs::remove(Path(name));
  }
  // shard sets: incomplete, or generated over different ranges
  ExpectRefused("merge --out M.h5 S0.h5", {"1 of 2 shards given; missing shard 1"}, 1);
  ExpectRefused("merge --out M.h5 S0.h5 T1.h5", {"T1.h5 was generated over indices [0, 6)"}, 1);
  ExpectRefused("merge --out M.h5 S0.h5 S0.h5 S1.h5", {"are both shard 0"}, 1);
}

// Untrusted captures name nothing outside themselves, and no message echoes a file that is not
// the one being parsed: absolute, '..' and linked-out paths in labels.csv are refused by row.
TEST_F(HostileInputTest, CaptureDirectoriesAreConfinedToThemselves) {
  TempDir outside;
  const fs::path cap = outside.path() / "CAP";
  fs::create_directories(cap);
  fs::copy_file(Path("RUN/config.yaml"), cap / "capture.yaml");
  fs::copy_file(Path("X.wav"), cap / "a.wav");
  fs::copy_file(Path("X.wav"), outside.path() / "secret.wav");
  fs::create_symlink("../secret.wav", cap / "b.wav");
  const std::string import =
      "import --layout capture --min-duration-s 0.5 --out I.h5 --in " + cap.string();
  auto labels = [&](const std::string& rows) {
    std::ofstream(cap / "labels.csv") << "file,z_m,theta_rad,robot_log\n" << rows;
  };
  labels((outside.path() / "secret.wav").string() + ",0,0,\n");
  ExpectRefused(import, {"labels.csv:2: file '", "is not a file inside the capture"}, 1);
  labels("../secret.wav,0,0,\nb.wav,0,0,\n");
  ExpectRefused(import,
                {"labels.csv:2: file '../secret.wav' is not a file inside",
                 "labels.csv:3: file 'b.wav' is not a file inside"},
                1);
  // a robot log outside: refused by row, and nothing of that file is printed
  labels("a.wav,0,0,/etc/passwd\n");
  CliRun run = RunCli(import, dir_->path().string());
  EXPECT_EQ(run.exit_code, 1) << run.err;
  EXPECT_THAT(run.err, ::testing::HasSubstr("robot_log '/etc/passwd' is not a file inside"));
  EXPECT_EQ(run.err.find("root:"), std::string::npos) << run.err;
  // a robot log inside that is another kind of file: its line is not echoed either
  fs::copy_file("/etc/passwd", cap / "log.csv");
  labels("a.wav,0,0,log.csv\n");
  run = RunCli(import, dir_->path().string());
  EXPECT_EQ(run.exit_code, 1) << run.err;
  EXPECT_THAT(run.err, ::testing::HasSubstr("that is not a CSV header"));
  EXPECT_EQ(run.err.find("root:"), std::string::npos) << run.err;
  // capture.yaml names no file: the noise clip is the capture's noise.wav
  labels("a.wav,0,0,\n");
  {
    std::ifstream in(cap / "capture.yaml");
    std::string text((std::istreambuf_iterator<char>(in)), {});
    const size_t at = text.find("gating_noise_wav:");
    ASSERT_NE(at, std::string::npos);
    text.replace(at, text.find('\n', at) - at,
                 "gating_noise_wav: " + (outside.path() / "secret.wav").string());
    std::ofstream(cap / "capture.yaml") << text;
  }
  ExpectRefused(import, {"capture.yaml: features.gating_noise_wav names a file"}, 1);
}

// Special files are refused by type before any read (a FIFO blocked the read forever, /dev/zero
// as .npy grew to 9 GB), and file-system refusals (a name too long, a link loop, no permission)
// are errors naming the path, not internal errors.
TEST_F(HostileInputTest, SpecialFilesAndFileSystemRefusalsAreErrorsNamingThePath) {
  TempDir special;
  const fs::path fifo = special.path() / "fifo";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  fs::create_symlink(fifo, special.path() / "fifo.h5");
  fs::create_symlink(fifo, special.path() / "fifo.yaml");
  fs::create_symlink(fifo, special.path() / "fifo.csv");
  const std::string f = fifo.string();
  ExpectRefused("inspect " + f, {"fifo: is a FIFO, not a regular file"}, 1);
  ExpectRefused("inspect " + f + ".h5", {"fifo.h5: is a FIFO"}, 1);
  ExpectRefused("eval --model RUN --data " + f + ".h5", {"fifo.h5: is a FIFO"}, 1);
  ExpectRefused("--config " + f + ".yaml config", {"fifo.yaml: is a FIFO"}, 1);
  ExpectRefused(kShortRecordArgs + "features --in X.wav --out F.h5 --proprio " + f + ".csv",
                {"fifo.csv: is a FIFO"}, 1);
  // a trial whose x_t.npy is a FIFO, then /dev/zero
  const fs::path trials = special.path() / "trials";
  fs::create_directories(trials);
  fs::copy(Path("TR/trial0"), trials / "trial0");
  fs::remove(trials / "trial0/x_t.npy");
  fs::create_symlink(fifo, trials / "trial0/x_t.npy");
  const std::string import =
      "import --layout trial --min-duration-s 0.5 --out I.h5 --in " + trials.string();
  ExpectRefused(import, {"x_t.npy: is a FIFO"}, 1);
  fs::remove(trials / "trial0/x_t.npy");
  fs::create_symlink("/dev/zero", trials / "trial0/x_t.npy");
  ExpectRefused(import, {"x_t.npy: is a character device"}, 1);
  // a name too long and a link loop: exit 1 naming the path (they were internal errors, exit 3)
  const std::string long_name = std::string(300, 'n') + ".h5";
  ExpectRefused(kShortRecordArgs + "generate --count 2 --out " + long_name, {"File name too long"},
                1);
  ExpectRefused("inspect " + long_name, {long_name}, 1);
  fs::create_symlink(special.path() / "loop_b", special.path() / "loop_a");
  fs::create_symlink(special.path() / "loop_a", special.path() / "loop_b");
  const std::string loop = (special.path() / "loop_a").string();
  ExpectRefused("inspect " + loop, {"loop_a", "Too many levels of symbolic links"}, 1);
  ExpectRefused(kShortRecordArgs + kTinyModelArgs + "train --data D.h5 --out " + loop, {"loop_a"},
                1);
  ExpectRefused("eval --model " + loop + " --data D.h5", {"loop_a"}, 1);
  // no permission (only without root: root reads every file)
  if (::geteuid() != 0) {
    fs::copy_file(Path("D.h5"), special.path() / "locked.h5");
    fs::permissions(special.path() / "locked.h5", fs::perms::none);
    ExpectRefused("inspect " + (special.path() / "locked.h5").string(),
                  {"locked.h5: cannot be read: Permission denied"}, 1);
  }
}

}  // namespace
}  // namespace sonicboom::experiments
