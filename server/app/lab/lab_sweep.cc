#include "app/lab/lab_sweep.h"

#include <unistd.h>

#include <atomic>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <system_error>

#include "io/scene_writer.h"

namespace conica::lab {
namespace fs = std::filesystem;

namespace {
std::string read_file(const fs::path& p, bool* ok) {
  std::ifstream in(p, std::ios::binary);
  *ok = static_cast<bool>(in);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}
}  // namespace

bool parse_shard(const std::string& s, int* i, int* n) {
  const size_t slash = s.find('/');
  if (slash == std::string::npos) return false;
  try {
    size_t a = 0, b = 0;
    *i = std::stoi(s.substr(0, slash), &a);
    *n = std::stoi(s.substr(slash + 1), &b);
    if (a != slash || b != s.size() - slash - 1) return false;
  } catch (...) {
    return false;
  }
  return *n >= 1 && *i >= 0 && *i < *n;
}

std::string write_atomic(const std::string& path, const std::string& text) {
  // A temporary name of this writer alone: shards of one sweep start together and write the
  // same key file; with one shared temporary name, one shard's rename took the other's file.
  static std::atomic<unsigned> serial{0};
  const std::string tmp =
      path + ".part." + std::to_string(::getpid()) + "." + std::to_string(serial.fetch_add(1));
  if (std::string e = io::write_text_file(tmp, text); !e.empty()) return e;
  std::error_code ec;
  fs::rename(tmp, path, ec);
  if (ec) return path + ": cannot write (" + ec.message() + ")";
  return {};
}

void Sweep::add_options(CLI::App* cmd) {
  cmd->add_option("--shard", shard_text_,
                  "i/N: run the units k with k % N == i into PREFIX.units/ (resumable)")
      ->capture_default_str();
  cmd->add_flag("--merge", merge_,
                "run nothing: check that every unit of PREFIX.units/ is there and write "
                "PREFIX.csv");
}

std::string Sweep::unit_path(int k) const { return dir_ + "/unit-" + std::to_string(k) + ".csv"; }

std::string Sweep::begin(const std::string& prefix, const std::string& key, int units) {
  units_ = units;
  done_.assign(units, false);
  if (!parse_shard(shard_text_, &index_, &count_))
    return "--shard " + shard_text_ + ": expected i/N with 0 <= i < N";
  sharded_ = shard_text_ != "0/1" || merge_;
  start_ = std::chrono::steady_clock::now();
  finished_ = 0;
  todo_ = merge_ ? 0 : units;
  if (!sharded_) return {};
  dir_ = prefix + ".units";
  const fs::path key_path = fs::path(dir_) / "key";
  std::error_code ec;
  if (fs::exists(key_path)) {
    bool ok = false;
    const std::string old = read_file(key_path, &ok);
    if (!ok) return key_path.string() + ": cannot read";
    if (old != key + "\n")
      return dir_ + " holds units of other options (" + old.substr(0, old.size() - 1) +
             "; now: " + key + "): remove it or use another --out";
  } else if (merge_) {
    return dir_ + ": no units (run the shards first)";
  } else {
    fs::create_directories(dir_, ec);
    if (ec) return dir_ + ": cannot create (" + ec.message() + ")";
    if (std::string e = write_atomic(key_path.string(), key + "\n"); !e.empty()) return e;
  }
  todo_ = 0;
  for (int k = 0; k < units; ++k) {
    done_[k] = fs::exists(unit_path(k));
    todo_ += runs(k) ? 1 : 0;
  }
  return {};
}

bool Sweep::runs(int k) const {
  if (merge_) return false;
  if (!sharded_) return true;
  return k % count_ == index_ && !done_[k];
}

std::string Sweep::put(int k, const std::string& rows) {
  const double t = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  ++finished_;
  const double eta = finished_ < todo_ ? t / finished_ * (todo_ - finished_) : 0.0;
  std::printf("[%d/%d] unit %d done, %.1f s, ETA %.0f s\n", finished_, todo_, k, t, eta);
  std::fflush(stdout);
  if (!sharded_) return {};
  done_[k] = true;
  return write_atomic(unit_path(k), rows);
}

std::string Sweep::merged(std::string* rows) const {
  rows->clear();
  std::string missing;
  int n_missing = 0;
  for (int k = 0; k < units_; ++k) {
    bool ok = false;
    const std::string text = read_file(unit_path(k), &ok);
    if (!ok) {
      if (++n_missing <= 8) missing += (missing.empty() ? "" : ", ") + std::to_string(k);
      continue;
    }
    *rows += text;
  }
  if (n_missing > 0)
    return dir_ + ": " + std::to_string(n_missing) + " of " + std::to_string(units_) +
           " units missing (" + missing + (n_missing > 8 ? ", ..." : "") +
           "): run their shards first";
  return {};
}

std::string Sweep::summary() const {
  int mine = 0, before = 0;
  for (int k = 0; k < units_; ++k)
    if (k % count_ == index_) {
      ++mine;
      before += done_[k] ? 1 : 0;
    }
  return "shard " + std::to_string(index_) + "/" + std::to_string(count_) + ": " +
         std::to_string(mine) + " of " + std::to_string(units_) + " units (" +
         std::to_string(before) + " done before)";
}

}  // namespace conica::lab
