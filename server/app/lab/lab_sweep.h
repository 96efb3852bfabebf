// Lab sweeps split over processes (a Slurm job array, or a loop in a shell): a sweep is a list of
// independent units, each giving CSV rows. `--shard i/N` runs the units k with k % N == i and
// writes each unit's rows to PREFIX.units/unit-K.csv as it finishes (through a temporary file and
// a rename), so an interrupted shard, run again, skips what is done; `--merge` checks that every
// unit is there, made with the same options, and writes PREFIX.csv with the rows in unit order:
// the bytes one process writes, apart from wall-time columns. Without either flag a sweep runs
// every unit in this process and writes PREFIX.csv, as before.
#pragma once

#include <CLI/CLI.hpp>
#include <chrono>
#include <string>
#include <vector>

namespace conica::lab {

// "i/N" -> shard i of N (0 <= i < N).
bool parse_shard(const std::string& text, int* i, int* n);

// Writes `text` to `path` through PATH.part in the same folder and a rename. Returns the error.
std::string write_atomic(const std::string& path, const std::string& text);

class Sweep {
 public:
  // Adds --shard and --merge to `cmd`.
  void add_options(CLI::App* cmd);

  // Checks the options and opens PREFIX.units/ when sharded or merging; `key` is the sweep's
  // options as text (a store made with another key is refused, naming both), `units` the number
  // of units. Returns the error, empty on success.
  std::string begin(const std::string& prefix, const std::string& key, int units);

  bool merging() const { return merge_; }
  bool sharded() const { return sharded_; }
  // Whether this process runs unit k: it is in this shard and not done by an earlier run.
  bool runs(int k) const;
  // Records unit k's rows (CSV lines, each ending in '\n') and prints a progress line
  // ("[3/14] unit 8 done, 4.1 s, ETA 15 s"). Returns the error.
  std::string put(int k, const std::string& rows);
  // The rows of every unit in unit order, into *rows; error naming the missing units.
  std::string merged(std::string* rows) const;
  // "shard i/N: n of units units (m done before)" for the log.
  std::string summary() const;

 private:
  std::string shard_text_ = "0/1";
  bool merge_ = false, sharded_ = false;
  int index_ = 0, count_ = 1, units_ = 0, todo_ = 0, finished_ = 0;
  std::chrono::steady_clock::time_point start_;
  std::string dir_;
  std::vector<bool> done_;
  std::string unit_path(int k) const;
};

}  // namespace conica::lab
