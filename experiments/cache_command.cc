// `cache list` and `cache prune`: the mode cache's entries, their sizes and last use, against
// its budget (sonicboom/core/cache_dir.h).
#include <CLI/CLI.hpp>

#include <ctime>
#include <filesystem>
#include <optional>
#include <system_error>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "sonicboom/core/cache_dir.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/experiments/commands.h"

#include "internal/report.h"
#include "internal/subcommands.h"

namespace sonicboom::experiments {
namespace {

using nlohmann::json;

// --cache-dir, else the config's acoustics.mode_cache_dir, else the default; refused when none
// or when it is not a directory
std::string CacheCommandDir(const GlobalOptions& g, const std::string& option) {
  const std::string dir = option.empty() ? Resolve(g).acoustics.ModeCacheDir() : option;
  if (dir.empty()) {
    throw ConfigError(
        "there is no mode cache: HOME is unset and the user has no home directory; give "
        "--cache-dir DIR, or set SONICBOOM_CACHE_DIR or acoustics.mode_cache_dir");
  }
  std::error_code ec;
  if (std::filesystem::exists(dir, ec) && !std::filesystem::is_directory(dir, ec))
    throw IoError(fmt::format("{}: not a directory (the mode cache)", dir));
  return dir;
}

std::string CacheTimeUtc(int64_t ns) {
  const std::time_t t = static_cast<std::time_t>(ns / 1000000000);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof(buf), "%Y-%m-%d %H:%M:%S", &tm);
  return buf;
}

std::string CacheBudgetText(uint64_t budget) {
  return budget == 0 ? std::string("no cap") : "a budget of " + internal::FormatBytes(budget);
}

CommandResult RunCacheList(const GlobalOptions& g, const std::string& dir_option) {
  const std::string dir = CacheCommandDir(g, dir_option);
  const uint64_t budget = internal::CacheBudgetBytes();
  uint64_t total = 0;
  int64_t count = 0;
  json entries = json::array();
  std::string rows;
  for (const internal::CacheEntry& e : internal::ListCacheEntries(dir)) {
    const std::string state = !e.regular  ? "damaged (not a regular file)"
                              : e.stale   ? "left by a stopped writer"
                              : e.partial ? "being written"
                                          : "";
    if (e.regular && !e.partial) total += e.bytes, ++count;
    entries.push_back({{"name", e.name},
                       {"kind", e.kind},
                       {"bytes", e.bytes},
                       {"last_use_utc", CacheTimeUtc(e.last_use_ns)},
                       {"state", state}});
    rows += fmt::format("  {}  {:>9}  {}{}\n", CacheTimeUtc(e.last_use_ns),
                        internal::FormatBytes(e.bytes), e.name,
                        state.empty() ? "" : " (" + state + ")");
  }
  std::string text = fmt::format("mode cache {}: {} entries, {} of {} ({})\n", dir, count,
                                 internal::FormatBytes(total), CacheBudgetText(budget),
                                 internal::kCacheBudgetVariable);
  if (!rows.empty())
    text += "  last use (UTC)            size  entry (least recently used first)\n" + rows;
  const json j = {{"dir", dir},
                  {"budget_bytes", budget},
                  {"total_bytes", total},
                  {"entries_count", count},
                  {"entries", entries}};
  return {j.dump(), text};
}

CommandResult RunCachePrune(const GlobalOptions& g, const std::string& dir_option,
                            std::optional<uint64_t> max_bytes, bool all) {
  const std::string dir = CacheCommandDir(g, dir_option);
  const uint64_t budget = internal::CacheBudgetBytes();
  // 0 to PruneCache removes everything; a budget of 0 is no cap
  const uint64_t cap = all ? 0 : max_bytes ? *max_bytes : budget;
  const bool uncapped = !all && !max_bytes && budget == 0;
  std::string error;
  const internal::CachePruned p =
      internal::PruneCache(dir, uncapped ? UINT64_MAX : cap, "", &error);
  if (!error.empty()) throw IoError(error);
  std::string text =
      fmt::format("mode cache {}: removed {} file(s) ({}); {} entries ({}) remain, against {}\n",
                  dir, p.removed, internal::FormatBytes(p.removed_bytes), p.kept,
                  internal::FormatBytes(p.kept_bytes),
                  all         ? std::string("--all")
                  : max_bytes ? "--max-bytes " + internal::FormatBytes(cap)
                              : CacheBudgetText(budget));
  if (p.in_use > 0) text += fmt::format("  {} entries being read were kept\n", p.in_use);
  const json j = {{"dir", dir},
                  {"removed", p.removed},
                  {"removed_bytes", p.removed_bytes},
                  {"kept", p.kept},
                  {"kept_bytes", p.kept_bytes},
                  {"in_use", p.in_use},
                  {"cap_bytes", uncapped ? json(nullptr) : json(cap)}};
  return {j.dump(), text};
}

// --max-bytes: a size (ParseByteSize); anything else is a usage error naming it
CLI::Validator CacheSizeValidator() {
  return CLI::Validator(
      [](std::string& text) -> std::string {
        return internal::ParseByteSize(text)
                   ? std::string()
                   : "'" + text + "' is not a size in bytes (e.g. 500000000, 500M, 2G, 1GiB)";
      },
      "SIZE");
}

}  // namespace

void RegisterCache(CLI::App& app, GlobalOptions& g, Runner* run) {
  struct Options {
    std::string dir;
    std::string max_bytes;
    bool all = false;
  };
  auto o = std::make_shared<Options>();
  auto* cache = app.add_subcommand("cache", "the mode cache: its entries, sizes and budget");
  cache->require_subcommand(1);
  auto* list = cache->add_subcommand("list", "every entry, its size and last use, and the total");
  auto* prune = cache->add_subcommand(
      "prune", "remove entries least recently used first, down to the budget or --max-bytes");
  for (CLI::App* sub : {list, prune}) {
    sub->add_option("--cache-dir", o->dir,
                    "the cache directory (default: acoustics.mode_cache_dir, $SONICBOOM_CACHE_DIR "
                    "or ~/.cache/sonicboom/modes)");
  }
  auto* max = prune
                  ->add_option("--max-bytes", o->max_bytes,
                               "keep at most this much (a size: 500M, 2G; default the budget, "
                               "$SONICBOOM_CACHE_MAX_BYTES or 1G)")
                  ->check(CacheSizeValidator());
  prune->add_flag("--all", o->all, "remove every entry not being read")->excludes(max);
  list->callback([&g, run, o] { *run = [&g, o] { return RunCacheList(g, o->dir); }; });
  prune->callback([&g, run, o] {
    *run = [&g, o] {
      const std::optional<uint64_t> max_bytes =
          o->max_bytes.empty() ? std::nullopt : internal::ParseByteSize(o->max_bytes);
      return RunCachePrune(g, o->dir, max_bytes, o->all);
    };
  });
}

}  // namespace sonicboom::experiments
