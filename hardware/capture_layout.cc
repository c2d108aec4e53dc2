// Our capture layout: WAVs, labels.csv, optional robot logs and noise.wav (docs/captures.md).
#include <algorithm>
#include <cctype>
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
constexpr const char* kOptional[] = {"object", "material", "robot_log", "time_s"};

std::vector<std::string> SplitCsv(std::string line) {
  if (!line.empty() && line.back() == '\r') line.pop_back();
  std::vector<std::string> cells;
  std::stringstream ss(line);
  for (std::string cell; std::getline(ss, cell, ',');) cells.push_back(cell);
  if (!line.empty() && line.back() == ',') cells.emplace_back();
  return cells;
}

// A plain decimal number: [+-] digits [. digits] [e [+-] digits], blanks around it allowed.
bool IsDecimal(const std::string& s) {
  size_t i = s.find_first_not_of(" \t"), digits = 0;
  const size_t end = s.find_last_not_of(" \t") + 1;
  if (i == std::string::npos) return false;
  auto run = [&] {
    const size_t from = i;
    while (i < end && std::isdigit(static_cast<unsigned char>(s[i]))) ++i;
    return i - from;
  };
  if (s[i] == '+' || s[i] == '-') ++i;
  digits = run();
  if (i < end && s[i] == '.') {
    ++i;
    digits += run();
  }
  if (digits == 0) return false;
  if (i < end && (s[i] == 'e' || s[i] == 'E')) {
    ++i;
    if (i < end && (s[i] == '+' || s[i] == '-')) ++i;
    if (run() == 0) return false;
  }
  return i == end;
}

// A cell's number in decimal notation: strtod would also read hexadecimal (0x10 is 16) and hex
// floats (0x1p-4 is 0.0625), which no one writes for metres on purpose.
double Number(const std::string& cell, const std::string& where, const std::string& column) {
  if (IsDecimal(cell)) {
    try {
      return std::stod(cell);
    } catch (const std::exception&) {
    }
  }
  const bool hex = cell.find_first_of("xX") != std::string::npos;
  throw IoError(fmt::format("{}: {} '{}' is not a number{}", where, column, cell,
                            hex ? " (decimal notation only: hexadecimal is refused)" : ""));
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

// The optional time_s cell: the contact's time from the record's start, s (NaN, not known, when
// absent or empty); it must lie within the record.
void SetContactTime(const std::map<std::string, std::string>& row, const std::string& where,
                    const ImportSettings& s, StrikeSample* sample) {
  const auto cell = row.find("time_s");
  if (cell == row.end() || cell->second.empty()) return;
  const double t = Number(cell->second, where, "time_s");
  const double record_s = static_cast<double>(s.record_frames) / s.sample_rate_hz;
  if (!(t >= 0.0 && t < record_s)) {
    throw IoError(
        fmt::format("{}: time_s {} s lies outside the record [0, {} s)", where, t, record_s));
  }
  sample->label.time_s = t;
  sample->contacts[0].time_s = t;
}

// One labels.csv row as a capture: its WAV, label, contact names and optional robot log, every
// path confined to the capture directory (a capture may come from anyone).
StrikeSample LoadCapture(const fs::path& dir, const std::map<std::string, std::string>& row,
                         const std::string& where, const ImportSettings& s, LoadNotes* notes) {
  StrikeSample sample;
  sample.audio =
      CheckedRecord(InsideCapture(dir, row.at("file"), where, "file").string(), s, notes);
  SetLabel(Number(row.at("z_m"), where, "z_m"), Number(row.at("theta_rad"), where, "theta_rad"), s,
           where, &sample);
  SetContactTime(row, where, s, &sample);
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
  if (line.rfind("\xEF\xBB\xBF", 0) == 0) line.erase(0, 3);  // a UTF-8 byte order mark
  const std::vector<std::string> header = SplitCsv(line);
  for (const char* name : kRequired) {
    if (std::find(header.begin(), header.end(), name) == header.end()) {
      throw IoError(
          fmt::format("{}:1: header lacks the column '{}' (file,z_m,theta_rad required; "
                      "object,material,robot_log,time_s optional)",
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
    entries.push_back({(dir / file).string(), index,
                       [dir, row, where, problem](const ImportSettings& s, LoadNotes* notes) {
                         if (!problem.empty()) throw IoError(problem);
                         return LoadCapture(dir, row, where, s, notes);
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
                       [file](const ImportSettings&, LoadNotes*) -> StrikeSample {
                         throw IoError(fmt::format("{}: no row in labels.csv", file));
                       }});
  }
  return entries;
}

}  // namespace sonicboom::hardware::internal
