// Internal to conica_io: what the legacy VTK ASCII reader (vtk_reader.cc) and the BINARY reader
// (vtk_binary_reader.cc) share: the cell lists and their filing into a MeshAssembler.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "io/binary_reader.h"
#include "io/readers.h"

namespace conica::io::detail {

// The name of a VTK cell type, for messages and skipped-cell counts (vtk_reader.cc).
std::string cell_type_name(std::int64_t type);

// CELLS and CELL_TYPES as read, in the offsets/connectivity layout of 5.1.
struct Cells {
  std::vector<std::int64_t> offsets{0};  // (num_cells + 1)
  std::vector<std::int64_t> connectivity;
  std::vector<std::int64_t> lines;  // (num_cells) line (ASCII) or byte offset (BINARY) of
                                    // each cell, for messages
  std::vector<std::int64_t> types;  // (num_cells)
  int types_line = 0;
  std::int64_t count() const { return static_cast<std::int64_t>(offsets.size()) - 1; }
};

// Files the cells into `out`; `fail(where, what)` reports a cell of the wrong size at its line
// or byte offset.
template <class Fail>
void assemble(const Cells& cells, const std::vector<std::int64_t>& regions, bool have_regions,
              MeshAssembler* out, Fail fail) {
  const std::vector<int> no_tags;
  for (std::int64_t c = 0; c < cells.count(); ++c) {
    const std::int64_t* p = cells.connectivity.data() + cells.offsets[c];
    const std::int64_t k = cells.offsets[c + 1] - cells.offsets[c];
    const std::int64_t type = cells.types[c];
    const int expected = type == 10 ? 4 : type == 12 ? 8 : type == 5 ? 3 : -1;
    if (expected > 0 && k != expected) {
      fail(cells.lines[c], "cell " + std::to_string(c) + " (" + cell_type_name(type) + ") has " +
                               std::to_string(k) + " points, expected " + std::to_string(expected));
    }
    const bool tagged = have_regions && static_cast<std::int64_t>(regions.size()) == cells.count();
    const std::vector<int> tags = tagged ? std::vector<int>{static_cast<int>(regions[c])} : no_tags;
    auto at = [&](int i) { return static_cast<int>(p[i]); };
    if (type == 10) {
      out->add_tetrahedron({at(0), at(1), at(2), at(3)}, tags);
    } else if (type == 12) {
      out->add_hexahedron({at(0), at(1), at(2), at(3), at(4), at(5), at(6), at(7)}, tags);
    } else if (type == 5) {
      out->add_triangle({at(0), at(1), at(2)});
    } else {
      out->skip(cell_type_name(type));
    }
  }
}

// A BINARY file from after its BINARY line (vtk_binary_reader.cc).
MeshFile read_vtk_binary(ByteReader& in, std::string_view version);

}  // namespace conica::io::detail
