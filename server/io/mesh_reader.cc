#include "io/mesh_reader.h"

#include <fstream>
#include <new>
#include <sstream>

#include "io/readers.h"

namespace conica::io {

namespace detail {

MeshAssembler::MeshAssembler() {}

Region& MeshAssembler::region(int tag) {
  Region& r = regions_[tag];
  r.id = tag;
  return r;
}

void MeshAssembler::add_tetrahedron(const std::array<int, 4>& nodes, const std::vector<int>& tags) {
  const int index = static_cast<int>(file_.mesh.tetrahedra.size());
  file_.mesh.tetrahedra.push_back(nodes);
  for (const int tag : tags) {
    if (tag != 0 || zero_is_region) region(tag).tetrahedra.push_back(index);
  }
}

void MeshAssembler::add_hexahedron(const std::array<int, 8>& nodes, const std::vector<int>& tags) {
  const int index = static_cast<int>(file_.mesh.hexahedra.size());
  file_.mesh.hexahedra.push_back(nodes);
  for (const int tag : tags) {
    if (tag != 0 || zero_is_region) region(tag).hexahedra.push_back(index);
  }
}

void MeshAssembler::skip(const std::string& type_name) {
  ++file_.skipped_elements;
  ++file_.skipped_types[type_name];
}

MeshFile MeshAssembler::finish(const std::map<int, std::string>& names) {
  for (auto& [tag, r] : regions_) {
    const auto it = names.find(tag);
    r.name = it != names.end() ? it->second : "region_" + std::to_string(tag);
    file_.mesh.regions.push_back(std::move(r));
  }
  regions_.clear();
  return std::move(file_);
}

}  // namespace detail

std::string convert_command(const std::string& path) {
  const std::size_t slash = path.find_last_of('/');
  const std::size_t dot = path.find_last_of('.');
  const bool has_ext = dot != std::string::npos && (slash == std::string::npos || dot > slash + 1);
  const std::string stem = has_ext ? path.substr(0, dot) : path;
  std::string out = stem + ".msh";
  if (out == path) out = stem + "-converted.msh";
  auto quote = [](const std::string& s) {
    for (const char c : s) {
      const bool plain = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') ||
                         (c >= '0' && c <= '9') || c == '/' || c == '.' || c == '_' || c == '-';
      if (!plain) {
        std::string q = "'";
        for (const char d : s) q += d == '\'' ? std::string("'\\''") : std::string(1, d);
        return q + "'";
      }
    }
    return s;
  };
  return "meshio convert --output-format gmsh22 " + quote(path) + " " + quote(out);
}

Result<MeshFile> parse_mesh(std::string_view text, const std::string& name) {
  detail::LineReader in(text, name);
  try {
    std::string_view first;
    if (!in.next_nonblank(&first)) in.fail_at(1, "empty file, expected a Gmsh or VTK mesh");
    const std::string_view head = detail::Fields(first).rest();
    std::string_view keyword;
    detail::Fields(head).next(&keyword);
    if (keyword == "$NOD") {
      return detail::read_gmsh1(in);
    }
    if (head.rfind("$MeshFormat", 0) == 0) return detail::read_gmsh(in, text);
    if (head.rfind("# vtk DataFile Version", 0) == 0) return detail::read_vtk(in, head, text);
    const std::string convert = "; convert it with `" + convert_command(name) + "`";
    if (head.rfind("<?xml", 0) == 0 || head.rfind("<VTKFile", 0) == 0) {
      in.fail("XML mesh files (VTK .vtu/.vtk XML, XDMF...) are not supported" + convert);
    }
    if (text.find('\0') != std::string_view::npos) {
      in.fail("binary file of unknown format, expected a Gmsh or legacy VTK mesh" + convert);
    }
    in.fail("unrecognised mesh format: first line is '" + std::string(head.substr(0, 60)) +
            "', expected $NOD, $MeshFormat or # vtk DataFile" + convert);
  } catch (const detail::ParseError& e) {
    return Error{e.message};
  } catch (const std::bad_alloc&) {
    return Error{in.message("out of memory while reading")};
  }
}

Result<MeshFile> read_mesh(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) return Error{path + ": cannot open file"};
  std::ostringstream buf;
  buf << f.rdbuf();
  if (f.bad()) return Error{path + ": read error"};
  return parse_mesh(buf.str(), path);
}

}  // namespace conica::io
