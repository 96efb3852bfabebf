// Force-displacement curves of compression tests, in the CSV form of the phantom tests
// (shared/data/phantoms): metadata lines, then a header row naming every column with its unit in
// parentheses, then one row of numbers per sample; cells split at commas, blanks and a trailing
// ';' around a cell ignored. Compression and load are positive in compression.
//
//   Time (s),Compression (mm),Load (N),Engineering Strain [-],...
//   0.000000,0.000000,0.022750,-0.000000,...
//
// Every error names the file and the line, and the column where there is one:
//   EF30_0T_A1.csv:8: no column "Load" (columns: Time (s), Compression (mm))
//   EF30_0T_A1.csv:412: column 3 (Load (N)): 'nan' is not a finite number
//   EF30_0T_A1.csv:1344: column 2 (Compression (m)): reaches 20 m, more than the specimen's
//     height of 0.03 m: the values look like millimetres
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "io/result.h"

namespace conica::io {

struct CurveSample {
  double displacement = 0;  // m, plate travel, compression positive
  double force = 0;         // N, compression positive
};

struct CurveRequest {
  std::string displacement_column = "Compression";  // header name before " (unit)": mm or m
  std::string force_column = "Load";                // N or kN
  // m, the specimen's height along the load. It checks the units (a compression above the
  // height, or below a thousandth of it, is in the other unit) and the strain reached.
  // 0: the file's "Height: <number><mm|m>" line when it has one, else no such checks.
  double height = 0;
  // The curve must reach this engineering strain of the height (0: no requirement).
  double max_strain = 0;
};

struct ForceCurve {
  std::vector<CurveSample> samples;   // the loading branch: rows up to the largest compression
  std::string displacement_unit;      // "mm" or "m", as the header says
  std::string force_unit;             // "N" or "kN"
  double height = 0;                  // m, the height the checks used (0: none known)
  double file_height = 0;             // m, the file's own "Height:" line (0: none)
  int rows = 0;                       // data rows in the file (the unloading branch too)
  int last_line = 0;                  // line of the loading branch's last row
  std::vector<std::string> warnings;  // "file:line: ..." for what was accepted with a doubt
};

// Reads a curve from `text`; `name` (the file) starts every message.
Result<ForceCurve> parse_curve(std::string_view text, const std::string& name,
                               const CurveRequest& request = {});
// Reads the curve file at `path`.
Result<ForceCurve> read_curve(const std::string& path, const CurveRequest& request = {});

}  // namespace conica::io
