// No shell between the CLI and the programs it starts: every path a command reads or writes may
// hold quotes, `;`, `$( )` and newlines, and reaches the file system (and the plotting script)
// as the same bytes.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "common/test_util.h"

namespace sonicboom::experiments {
namespace {

namespace fs = std::filesystem;
using sonicboom::testing::CliRun;
using sonicboom::testing::RunProgram;
using sonicboom::testing::SplitArgs;
using sonicboom::testing::TempDir;

// The words of `fixed` (shell-style, SplitArgs) then `paths` as they are.
std::vector<std::string> Argv(const std::string& fixed, const std::vector<std::string>& paths) {
  std::vector<std::string> argv = {SONICBOOM_CLI};
  for (std::string& w : SplitArgs(fixed)) argv.push_back(w);
  argv.insert(argv.end(), paths.begin(), paths.end());
  return argv;
}

TEST(ShellFreePathsTest, QuotesSemicolonsSubstitutionsAndNewlinesArePlainBytesOfAPath) {
  TempDir dir;
  const std::string cwd = dir.path().string();
  // a directory whose name a shell would split, substitute and run
  const std::string odd = "it's; $(touch PWNED) `touch PWNED2` \"q\"\nline two';touch PWNED3;'";
  const fs::path d = dir.path() / odd;
  fs::create_directories(d);
  auto at = [&](const std::string& name) { return (d / name).string(); };
  fs::copy_file(fs::path(SONICBOOM_SOURCE_DIR) / "scripts" / "plot.py", at("pl'ot;$(x).py"));
  const std::string short_args = sonicboom::testing::kShortRecordArgs + "-q ";
  auto must = [&](const std::vector<std::string>& argv) {
    const CliRun run = RunProgram(argv, cwd);
    EXPECT_EQ(run.exit_code, 0) << argv.back() << "\n" << run.err;
    return run;
  };
  must(Argv(short_args + "generate --count 8 --out", {at("d'a;ta$(x).h5")}));
  must(Argv(short_args + "synth --index 2 --out", {at("s\"t;r$(x)\nike.wav")}));
  // the plotting script started with the odd names as its arguments
  must(Argv(short_args + "inspect", {at("d'a;ta$(x).h5"), "--png", at("fi'g;$(x)\n.png"),
                                     "--plot", at("pl'ot;$(x).py")}));
  EXPECT_TRUE(fs::is_regular_file(at("fi'g;$(x)\n.png")));
  EXPECT_GT(fs::file_size(at("fi'g;$(x)\n.png")), 1000u);
  must(Argv(short_args + sonicboom::testing::kTinyModelArgs + "--set train.epochs=1 train --data",
            {at("d'a;ta$(x).h5"), "--out", at("r'u;n$(x)")}));
  const CliRun located = must(Argv(short_args + "--json localize --model",
                                   {at("r'u;n$(x)"), "--wav", at("s\"t;r$(x)\nike.wav")}));
  EXPECT_NE(located.out.find("\"z_m\""), std::string::npos) << located.out;
  // nothing ran: no file the substitutions would have made, anywhere under the workspace
  for (const auto& entry : fs::recursive_directory_iterator(dir.path())) {
    EXPECT_EQ(entry.path().filename().string().rfind("PWNED", 0), std::string::npos)
        << entry.path();
  }
  EXPECT_FALSE(fs::exists(fs::current_path() / "PWNED"));
}

// A plot that fails says how (the script's exit status and its last stderr line), not a guess.
TEST(ShellFreePathsTest, AFailingPlotScriptIsReportedAsWhatItWas) {
  TempDir dir;
  const std::string cwd = dir.path().string();
  const std::string short_args = sonicboom::testing::kShortRecordArgs + "-q ";
  ASSERT_EQ(RunProgram(Argv(short_args + "generate --count 4 --out D.h5", {}), cwd).exit_code, 0);
  std::ofstream(dir.path() / "bad.py") << "import sys\nsys.stderr.write('the axes are gone\\n')\n"
                                          "sys.exit(3)\n";
  const CliRun run =
      RunProgram(Argv("inspect D.h5 --png F.png --plot bad.py", {}), cwd);
  EXPECT_EQ(run.exit_code, 1) << run.err;
  EXPECT_NE(run.err.find("exit status 3: the axes are gone"), std::string::npos) << run.err;
  EXPECT_EQ(run.err.find("matplotlib"), std::string::npos) << run.err;
  EXPECT_FALSE(fs::exists(dir.path() / "F.png"));
}

}  // namespace
}  // namespace sonicboom::experiments
