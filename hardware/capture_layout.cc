// Our capture layout: WAVs, labels.csv, optional robot logs and noise.wav (docs/captures.md).
#include <algorithm>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include <fmt/format.h>

#include "internal/import_common.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/core/files.h"
#include "sonicboom/hardware/capture.h"

namespace fs = std::filesystem;

namespace sonicboom::hardware::internal {
namespace {

constexpr const char* kRequired[] = {"file", "z_m", "theta_rad"};
constexpr const char* kOptional[] = {"object", "material", "robot_log"};

std::vector<std::string> SplitCsv(std::string line) {
  if (!line.empty() && line.back() == '\r') line.pop_back();
  std::vector<std::string> cells;
  std::stringstream ss(line);
  for (std::string cell; std::getline(ss, cell, ',');) cells.push_back(cell);
  if (!line.empty() && line.back() == ',') cells.emplace_back();
  return cells;
}

double Number(const std::string& cell, const std::string& where, const std::string& column) {
  try {
    size_t used = 0;
    const double v = std::stod(cell, &used);
    if (used == cell.size()) return v;
  } catch (const std::exception&) {
  }
  throw IoError(fmt::format("{}: {} '{}' is not a number", where, column, cell));
}

}  // namespace

fs::path InsideCapture(const fs::path& dir, const std::string& name, const std::string& where,
                       const char* column) {
  const fs::path relative(name);
  const bool climbs = std::any_of(relative.begin(), relative.end(),
                                  [](const fs::path& part) { return part == ".."; });
  if (name.empty() || relative.is_absolute() || climbs ||
      !IsWithin(ResolvedPath(dir / relative), ResolvedPath(dir))) {
    throw IoError(fmt::format(
        "{}: {} '{}' is not a file inside the capture directory {} (names are relative to it, "
        "without '..', and links may not lead out of it)",
        where, column, name, dir.string()));
  }
  return dir / relative;
}

namespace {

// One labels.csv row as a capture: its WAV, label, contact names and optional robot log, every
// path confined to the capture directory (a capture may come from anyone).
StrikeSample LoadCapture(const fs::path& dir, const std::map<std::string, std::string>& row,
                         const std::string& where, const ImportSettings& s) {
  StrikeSample sample;
  sample.audio = CheckedRecord(InsideCapture(dir, row.at("file"), where, "file").string(), s);
  SetLabel(Number(row.at("z_m"), where, "z_m"), Number(row.at("theta_rad"), where, "theta_rad"), s,
           where, &sample);
  if (row.count("object")) sample.contacts[0].object = row.at("object");
  if (row.count("material")) sample.contacts[0].material = row.at("material");
  const auto log = row.find("robot_log");
  if (log == row.end() || log->second.empty()) {
    sample.proprio = HeldProprio(s.proprio_rows);
    return sample;
  }
  const std::string log_path = InsideCapture(dir, log->second, where, "robot_log").string();
  const Eigen::MatrixXf proprio = ReadProprioCsv(log_path);
  if (proprio.rows() < s.proprio_rows) {
    throw IoError(fmt::format("{}: {} rows, the model needs {} (strike.proprio_rows)", log_path,
                              proprio.rows(), s.proprio_rows));
  }
  sample.proprio = proprio.topRows(s.proprio_rows);
  return sample;
}

}  // namespace

std::vector<ImportEntry> ListCaptures(const std::string& dir_name) {
  const fs::path dir(dir_name);
  const fs::path labels = dir / "labels.csv";
  std::ifstream in(labels);
  if (!in)
    throw IoError(
        fmt::format("{}: missing (a capture directory needs labels.csv)", labels.string()));

  // header: the required columns, then any optional ones, nothing else
  std::string line;
  std::getline(in, line);
  const std::vector<std::string> header = SplitCsv(line);
  for (const char* name : kRequired) {
    if (std::find(header.begin(), header.end(), name) == header.end()) {
      throw IoError(
          fmt::format("{}:1: header lacks the column '{}' (file,z_m,theta_rad required; "
                      "object,material,robot_log optional)",
                      labels.string(), name));
    }
  }
  for (const std::string& name : header) {
    const bool known = std::count(std::begin(kRequired), std::end(kRequired), name) +
                           std::count(std::begin(kOptional), std::end(kOptional), name) ==
                       1;
    if (!known || std::count(header.begin(), header.end(), name) != 1) {
      throw IoError(fmt::format("{}:1: column '{}' is unknown or repeated", labels.string(), name));
    }
  }

  // one entry per row; a malformed row is a bad capture, reported with its line
  std::vector<ImportEntry> entries;
  std::set<std::string> labelled;
  for (int line_no = 2; std::getline(in, line); ++line_no) {
    if (line.empty() || line == "\r") continue;
    const std::string where = fmt::format("{}:{}", labels.string(), line_no);
    const std::vector<std::string> cells = SplitCsv(line);
    std::map<std::string, std::string> row;
    for (size_t j = 0; j < std::min(cells.size(), header.size()); ++j) row[header[j]] = cells[j];
    const std::string file = row.count("file") ? row["file"] : std::string();
    std::string problem;
    if (cells.size() != header.size()) {
      problem = fmt::format("{}: {} cells, the header has {}", where, cells.size(), header.size());
    } else if (!labelled.insert(file).second) {
      problem = fmt::format("{}: '{}' is labelled twice", where, file);
    }
    const auto index = static_cast<uint64_t>(entries.size());
    entries.push_back(
        {(dir / file).string(), index, [dir, row, where, problem](const ImportSettings& s) {
           if (!problem.empty()) throw IoError(problem);
           return LoadCapture(dir, row, where, s);
         }});
  }

  // WAVs without a label are bad captures too
  std::vector<std::string> unlabelled;
  for (const fs::directory_entry& e : fs::directory_iterator(dir)) {
    const std::string name = e.path().filename().string();
    if (e.path().extension() == ".wav" && name != "noise.wav" && !labelled.count(name)) {
      unlabelled.push_back(name);
    }
  }
  std::sort(unlabelled.begin(), unlabelled.end());
  for (const std::string& name : unlabelled) {
    const std::string file = (dir / name).string();
    entries.push_back({file, static_cast<uint64_t>(entries.size()),
                       [file](const ImportSettings&) -> StrikeSample {
                         throw IoError(fmt::format("{}: no row in labels.csv", file));
                       }});
  }
  return entries;
}

}  // namespace sonicboom::hardware::internal
