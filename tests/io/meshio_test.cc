// Binary mesh files as another program writes them: meshio (Debian's python3-meshio) writes a
// tetrahedral and a hexahedral mesh in Gmsh 2.2 and 4.1, binary and ASCII, and legacy VTK 4.2
// and 5.1, BINARY and ASCII, at test time (tests/io/write_meshio_meshes.py), together with the
// coordinates and cells it was given. The readers must return exactly those, the binary file
// the same mesh as its ASCII twin, and for damaged binary files an error naming the file, the
// byte offset and the field.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "io/mesh_reader.h"
#include "io/mesh_repair.h"

namespace conica::io {
namespace {

using ::testing::HasSubstr;
using ::testing::StartsWith;

int run(const std::string& cmd) {
  const int w = std::system(cmd.c_str());
  return WIFEXITED(w) ? WEXITSTATUS(w) : -1;
}

std::string slurp(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  std::ostringstream s;
  s << f.rdbuf();
  return s.str();
}

// What meshio was given (NAME.expected).
struct Expected {
  std::vector<Vec3> points;
  std::string cell_type;
  std::vector<std::vector<int>> cells;
  std::vector<int> physical22, physical41;
};

Expected read_expected(const std::string& path) {
  Expected e;
  std::ifstream f(path);
  std::string line;
  while (std::getline(f, line) && line.rfind("cells ", 0) != 0) {
    std::istringstream is(line);
    std::string x, y, z;
    is >> x >> y >> z;
    // strtod of Python's repr gives back the exact double meshio wrote.
    e.points.emplace_back(std::strtod(x.c_str(), nullptr), std::strtod(y.c_str(), nullptr),
                          std::strtod(z.c_str(), nullptr));
  }
  std::istringstream head(line);
  std::string word;
  std::size_t n = 0;
  head >> word >> e.cell_type >> n;
  for (std::size_t i = 0; i < n && std::getline(f, line); ++i) {
    std::istringstream is(line);
    std::vector<int> c;
    int v;
    while (is >> v) c.push_back(v);
    e.cells.push_back(c);
  }
  for (std::vector<int>* tags : {&e.physical22, &e.physical41}) {
    std::getline(f, line);  // "physical" / "physical41"
    std::getline(f, line);
    std::istringstream is(line);
    int v;
    while (is >> v) tags->push_back(v);
  }
  return e;
}

class MeshioTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new std::string(::testing::TempDir() + "conica_meshio_" + std::to_string(getpid()));
    std::filesystem::remove_all(*dir_);
    status_ = run("/usr/bin/python3 '" CONICA_SOURCE_DIR "/tests/io/write_meshio_meshes.py' '" +
                  *dir_ + "' 2>/dev/null");
  }
  static void TearDownTestSuite() {
    std::filesystem::remove_all(*dir_);
    delete dir_;
  }
  void SetUp() override {
    ASSERT_EQ(status_, 0) << "tests/io/write_meshio_meshes.py failed: is python3-meshio "
                             "installed (scripts/setup.sh)?";
  }
  static std::string path(const std::string& file) { return *dir_ + "/" + file; }

  static MeshFile read_ok(const std::string& file) {
    Result<MeshFile> r = read_mesh(path(file));
    EXPECT_TRUE(r.ok()) << file << ": " << (r.ok() ? "" : r.error());
    return r.ok() ? std::move(r).value() : MeshFile{};
  }

  static std::string* dir_;
  static int status_;
};

std::string* MeshioTest::dir_ = nullptr;
int MeshioTest::status_ = -1;

// The cells of `m` of the expected type, as index lists.
std::vector<std::vector<int>> cells_of(const Mesh& m, const std::string& type) {
  std::vector<std::vector<int>> out;
  if (type == "tetra") {
    for (const auto& t : m.tetrahedra) out.emplace_back(t.begin(), t.end());
  } else {
    for (const auto& h : m.hexahedra) out.emplace_back(h.begin(), h.end());
  }
  return out;
}

void expect_as_written(const MeshFile& f, const Expected& e, const std::string& file) {
  SCOPED_TRACE(file);
  const Mesh& m = f.mesh;
  ASSERT_EQ(m.nodes.size(), e.points.size());
  for (std::size_t i = 0; i < e.points.size(); ++i) {
    // Exact: the binary doubles are the ones meshio was given, bit for bit.
    ASSERT_EQ(m.nodes[i], e.points[i]) << "node " << i;
  }
  EXPECT_EQ(cells_of(m, e.cell_type), e.cells);
  EXPECT_EQ(e.cell_type == "tetra" ? m.hexahedra.size() : m.tetrahedra.size(), 0u);
  EXPECT_TRUE(m.triangles.empty());
  EXPECT_EQ(f.skipped_elements, 0);
  // The perturbed blocks are valid meshes with every element positive.
  EXPECT_TRUE(inspect(m).clean()) << to_string(inspect(m));
}

// Regions as (id, element indices).
std::map<int, std::vector<int>> regions_of(const Mesh& m, const std::string& type) {
  std::map<int, std::vector<int>> out;
  for (const Region& r : m.regions) out[r.id] = type == "tetra" ? r.tetrahedra : r.hexahedra;
  return out;
}

std::map<int, std::vector<int>> regions_from(const std::vector<int>& tags) {
  std::map<int, std::vector<int>> out;
  for (std::size_t i = 0; i < tags.size(); ++i) out[tags[i]].push_back(static_cast<int>(i));
  return out;
}

TEST_F(MeshioTest, BinaryFilesHoldExactlyWhatMeshioWrote) {
  for (const std::string name : {"tet", "hex"}) {
    const Expected e = read_expected(path(name + ".expected"));
    ASSERT_EQ(e.cells.size(), name == "tet" ? 60u : 18u);
    ASSERT_EQ(e.points.size(), name == "tet" ? 36u : 48u);

    const MeshFile g22 = read_ok(name + ".gmsh22.msh");
    EXPECT_EQ(g22.format, "gmsh 2.2 binary");
    expect_as_written(g22, e, name + ".gmsh22.msh");
    EXPECT_EQ(regions_of(g22.mesh, e.cell_type), regions_from(e.physical22));

    const MeshFile g41 = read_ok(name + ".gmsh41.msh");
    EXPECT_EQ(g41.format, "gmsh 4.1 binary");
    expect_as_written(g41, e, name + ".gmsh41.msh");
    EXPECT_EQ(regions_of(g41.mesh, e.cell_type), regions_from(e.physical41));

    for (const std::string v : {"vtk51", "vtk42"}) {
      const MeshFile vtk = read_ok(name + "." + v + ".vtk");
      EXPECT_EQ(vtk.format, v == "vtk51" ? "vtk 5.1 binary" : "vtk 4.2 binary");
      expect_as_written(vtk, e, name + "." + v + ".vtk");
    }
    // float points: the float32 values meshio wrote, widened.
    const Expected ef = read_expected(path(name + ".expected-float"));
    const MeshFile vf = read_ok(name + ".vtk42-float.vtk");
    expect_as_written(vf, ef, name + ".vtk42-float.vtk");
    EXPECT_NE(ef.points[1], e.points[1]);  // float really rounds these coordinates
  }
}

TEST_F(MeshioTest, BinaryAndAsciiGiveTheSameMesh) {
  for (const std::string name : {"tet", "hex"}) {
    for (const auto& [binary, ascii] :
         std::vector<std::pair<std::string, std::string>>{{".gmsh22.msh", ".gmsh22-ascii.msh"},
                                                          {".gmsh41.msh", ".gmsh41-ascii.msh"},
                                                          {".vtk51.vtk", ".vtk51-ascii.vtk"},
                                                          {".vtk42.vtk", ".vtk42-ascii.vtk"}}) {
      SCOPED_TRACE(name + binary);
      const MeshFile b = read_ok(name + binary), a = read_ok(name + ascii);
      EXPECT_EQ(b.format, a.format + " binary");
      EXPECT_EQ(b.mesh.nodes, a.mesh.nodes);
      EXPECT_EQ(b.mesh.tetrahedra, a.mesh.tetrahedra);
      EXPECT_EQ(b.mesh.hexahedra, a.mesh.hexahedra);
      ASSERT_EQ(b.mesh.regions.size(), a.mesh.regions.size());
      for (std::size_t i = 0; i < a.mesh.regions.size(); ++i) {
        EXPECT_EQ(b.mesh.regions[i].id, a.mesh.regions[i].id);
        EXPECT_EQ(b.mesh.regions[i].tetrahedra, a.mesh.regions[i].tetrahedra);
        EXPECT_EQ(b.mesh.regions[i].hexahedra, a.mesh.regions[i].hexahedra);
      }
    }
  }
}

// Gmsh binary files are written in the writer's byte order: the same 2.2 file with every number
// byte-swapped (as a big-endian machine writes it) gives the same mesh.
std::string swap_gmsh22(const std::string& le) {
  std::string s = le;
  auto swap = [&s](std::size_t at, int n) {
    for (int i = 0; i < n / 2; ++i) std::swap(s[at + i], s[at + n - 1 - i]);
  };
  const std::size_t marker = s.find("2.2 1 8\n") + 8;
  swap(marker, 4);
  std::size_t at = s.find("$Nodes\n") + 7;
  at = s.find('\n', at) + 1;
  const long nodes = std::strtol(le.c_str() + s.find("$Nodes\n") + 7, nullptr, 10);
  for (long i = 0; i < nodes; ++i, at += 28) {
    swap(at, 4);
    for (int k = 0; k < 3; ++k) swap(at + 4 + 8 * k, 8);
  }
  at = s.find("$Elements\n") + 10;
  long left = std::strtol(le.c_str() + at, nullptr, 10);
  at = s.find('\n', at) + 1;
  while (left > 0) {
    std::int32_t h[3];
    std::memcpy(h, le.data() + at, 12);  // little-endian host, as the test machines are
    for (int k = 0; k < 3; ++k) swap(at + 4 * k, 4);
    at += 12;
    const int per = h[0] == 4 ? 4 : 8;
    for (long e = 0; e < h[1]; ++e)
      for (int k = 0; k < 1 + h[2] + per; ++k, at += 4) swap(at, 4);
    left -= h[1];
  }
  return s;
}

TEST_F(MeshioTest, BigEndianGmshGivesTheSameMesh) {
  for (const std::string name : {"tet", "hex"}) {
    const std::string le = slurp(path(name + ".gmsh22.msh"));
    const std::string be = swap_gmsh22(le);
    ASSERT_NE(be, le);
    const Result<MeshFile> a = parse_mesh(le, "le.msh"), b = parse_mesh(be, "be.msh");
    ASSERT_TRUE(a.ok()) << a.error();
    ASSERT_TRUE(b.ok()) << b.error();
    EXPECT_EQ(a.value().mesh.nodes, b.value().mesh.nodes);
    EXPECT_EQ(a.value().mesh.tetrahedra, b.value().mesh.tetrahedra);
    EXPECT_EQ(a.value().mesh.hexahedra, b.value().mesh.hexahedra);
    EXPECT_EQ(regions_of(a.value().mesh, name == "tet" ? "tetra" : "hexahedron"),
              regions_of(b.value().mesh, name == "tet" ? "tetra" : "hexahedron"));
  }
}

// VTK 9 writes METADATA blocks (INFORMATION keys such as array ranges, ended by a blank line)
// after data arrays, POINTS among them: skipped in BINARY and ASCII files alike.
TEST_F(MeshioTest, VtkMetadataBlocksAreSkipped) {
  const std::string metadata =
      "METADATA\nINFORMATION 1\nNAME L2_NORM_RANGE LOCATION vtkDataArray\nDATA 2 0 1.7\n\n";
  for (const std::string file : {"tet.vtk42.vtk", "tet.vtk42-ascii.vtk"}) {
    std::string text = slurp(path(file));
    const std::size_t cells = text.find("CELLS ");
    ASSERT_NE(cells, std::string::npos);
    text.insert(cells, metadata);
    const Result<MeshFile> r = parse_mesh(text, file);
    ASSERT_TRUE(r.ok()) << r.error();
    expect_as_written(r.value(), read_expected(path("tet.expected")), file);
  }
}

// ---- refused formats: the meshio line that converts them, and it works -------------------

TEST_F(MeshioTest, VtuIsRefusedWithTheConvertCommandThatWorks) {
  const std::string vtu = path("tet.vtu"), msh = path("tet.msh");
  const Result<MeshFile> r = read_mesh(vtu);
  ASSERT_FALSE(r.ok());
  const std::string command = "meshio convert --output-format gmsh22 " + vtu + " " + msh;
  EXPECT_THAT(r.error(), StartsWith(vtu + ":1: XML mesh files"));
  EXPECT_THAT(r.error(), HasSubstr("`" + command + "`"));
  ASSERT_EQ(run(command + " >/dev/null 2>&1"), 0) << command;
  const MeshFile f = read_ok("tet.msh");
  EXPECT_EQ(f.format, "gmsh 2.2 binary");
  expect_as_written(f, read_expected(path("tet.expected")), "tet.msh");
}

TEST(MeshConvertCommand, NamesTheOutputBesideTheInputAndQuotes) {
  EXPECT_EQ(convert_command("in.vtu"), "meshio convert --output-format gmsh22 in.vtu in.msh");
  EXPECT_EQ(convert_command("a.b/mesh"),
            "meshio convert --output-format gmsh22 a.b/mesh a.b/mesh.msh");
  EXPECT_EQ(convert_command("x.msh"),
            "meshio convert --output-format gmsh22 x.msh x-converted.msh");
  EXPECT_EQ(convert_command("my liver.inp"),
            "meshio convert --output-format gmsh22 'my liver.inp' 'my liver.msh'");
  const Result<MeshFile> stl = parse_mesh("solid cube\nfacet normal 0 0 1\n", "cube.stl");
  ASSERT_FALSE(stl.ok());
  EXPECT_THAT(stl.error(), HasSubstr("unrecognised mesh format"));
  EXPECT_THAT(stl.error(), HasSubstr("`meshio convert --output-format gmsh22 cube.stl cube.msh`"));
}

// ---- damaged binary files ------------------------------------------------------------------

std::string replace(std::string s, std::string_view from, std::string_view to) {
  const std::size_t at = s.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at != std::string::npos) s.replace(at, from.size(), to);
  return s;
}

void put_u64(std::string* s, std::size_t at, std::uint64_t v) {
  for (int i = 0; i < 8; ++i) (*s)[at + i] = static_cast<char>((v >> (8 * i)) & 0xff);
}

void put_i32(std::string* s, std::size_t at, std::int32_t v) {
  for (int i = 0; i < 4; ++i)
    (*s)[at + i] = static_cast<char>((static_cast<std::uint32_t>(v) >> (8 * i)) & 0xff);
}

// Must fail with "name: byte <at>: ..." containing `what`.
void expect_byte_error(const std::string& text, std::size_t at, std::string_view what,
                       const std::string& name = "bad.msh") {
  const Result<MeshFile> r = parse_mesh(text, name);
  ASSERT_FALSE(r.ok()) << "parsed a damaged file";
  EXPECT_THAT(r.error(), StartsWith(name + ": byte " + std::to_string(at) + ": "));
  EXPECT_THAT(r.error(), HasSubstr(std::string(what)));
}

TEST_F(MeshioTest, WrongEndiannessMarkerIsNamed) {
  const std::string g = slurp(path("tet.gmsh22.msh"));
  const std::size_t marker = g.find("2.2 1 8\n") + 8;
  std::string bad = g;
  put_i32(&bad, marker, 2);
  expect_byte_error(bad, marker, "endianness marker: expected the integer 1");
  expect_byte_error(bad, marker, "found bytes 02 00 00 00");
  // An ASCII file that says binary.
  const std::string ascii = replace(slurp(path("tet.gmsh41-ascii.msh")), "4.1 0 8", "4.1 1 8");
  expect_byte_error(ascii, ascii.find("4.1 1 8\n") + 8, "is this an ASCII file?");
  // Only 8-byte data.
  const std::string four = replace(g, "2.2 1 8", "2.2 1 4");
  const Result<MeshFile> r = parse_mesh(four, "bad.msh");
  ASSERT_FALSE(r.ok());
  EXPECT_THAT(r.error(), StartsWith("bad.msh:2: data size 4"));
}

TEST_F(MeshioTest, CountsThatOverrunTheFileFailWithoutAllocating) {
  // 2.2: the node count is a text line.
  const std::string g22 = slurp(path("tet.gmsh22.msh"));
  const std::string more = replace(g22, "$Nodes\n36\n", "$Nodes\n1000000000000\n");
  expect_byte_error(more, more.find("$Nodes\n") + 7, "node count 1000000000000 needs");
  const std::string elements = replace(g22, "$Elements\n60\n", "$Elements\n61\n");
  // 61 announced, 60 in the block: the next block header is read from "\n$EndElements".
  const Result<MeshFile> r = parse_mesh(elements, "bad.msh");
  ASSERT_FALSE(r.ok());
  EXPECT_THAT(r.error(), StartsWith("bad.msh: byte "));
  // 4.1: size_t counts.
  std::string g41 = slurp(path("tet.gmsh41.msh"));
  const std::size_t nodes = g41.find("$Nodes\n") + 7;
  std::string huge = g41;
  put_u64(&huge, nodes + 8, 1000000000000000ull);
  expect_byte_error(huge, nodes + 8, "node count 1000000000000000 needs");
  huge = g41;
  put_u64(&huge, nodes + 8, ~0ull);
  expect_byte_error(huge, nodes + 8, "node count 18446744073709551615 is out of range");
  // The block's own count (after dim, tag, parametric) larger than the announced total.
  huge = g41;
  put_u64(&huge, nodes + 32 + 12, 37);
  expect_byte_error(huge, nodes + 32, "node blocks hold more than the 36 nodes announced");
  // VTK: a text count.
  const std::string vtk = slurp(path("tet.vtk51.vtk"));
  const std::string points = replace(vtk, "POINTS 36 double", "POINTS 36000000 double");
  expect_byte_error(points, points.find("POINTS"), "point count 36000000 needs 864000000 bytes",
                    "bad.vtk");
  const std::string cells = replace(vtk, "CELLS 61 240", "CELLS 61 2400000");
  expect_byte_error(cells, cells.find("CELLS"), "connectivity size", "bad.vtk");
}

TEST_F(MeshioTest, UnknownElementTypeInABinaryBlockIsNamed) {
  std::string g22 = slurp(path("hex.gmsh22.msh"));
  const std::size_t block = g22.find("$Elements\n18\n") + 13;
  put_i32(&g22, block, 99);
  expect_byte_error(g22, block, "unknown element type 99");
  std::string g41 = slurp(path("hex.gmsh41.msh"));
  const std::size_t block41 = g41.find("$Elements\n") + 10 + 32;
  put_i32(&g41, block41 + 8, 1000);
  expect_byte_error(g41, block41, "unknown element type 1000");
  // A known type that is not kept is skipped and counted, as in ASCII files: prisms.
  std::string prism = slurp(path("hex.gmsh22.msh"));
  put_i32(&prism, block, 17);  // hexahedron20: 20 nodes per record, so the data runs short
  const Result<MeshFile> r = parse_mesh(prism, "bad.msh");
  ASSERT_FALSE(r.ok());
  EXPECT_THAT(r.error(), HasSubstr("element count 18 needs"));
}

TEST_F(MeshioTest, TruncatedBinaryBlocksNameTheOffsetAndField) {
  const std::string g22 = slurp(path("tet.gmsh22.msh"));
  const std::size_t nodes = g22.find("$Nodes\n36\n") + 10;
  // Cut inside node 5's y coordinate: the count check already sees that 36 nodes do not fit.
  expect_byte_error(g22.substr(0, nodes + 5 * 28 + 12), nodes - 3,
                    "node count 36 needs 1008 bytes");
  const std::string vtk = slurp(path("hex.vtk42.vtk"));
  const std::size_t cells = vtk.find("CELL_TYPES 18\n") + 14;
  expect_byte_error(vtk.substr(0, cells + 4 * 7 + 2), vtk.find("CELL_TYPES"),
                    "cell type count 18 needs 72 bytes", "bad.vtk");
  // Non-finite coordinates are refused where they are.
  std::string nan = g22;
  const double q = std::numeric_limits<double>::quiet_NaN();
  std::memcpy(&nan[nodes + 2 * 28 + 4 + 8], &q, 8);
  expect_byte_error(nan, nodes + 2 * 28 + 12, "y coordinate of node 3 is not a finite number");
  // A node referenced by an element that the file does not define.
  std::string unknown = g22;
  const std::size_t element = g22.find("$Elements\n60\n") + 13 + 12;
  put_i32(&unknown, element + 4 * 3, 999);  // id, physical, elementary, first node
  expect_byte_error(unknown, element, "element 1 references unknown node 999");
}

// Every prefix and many byte corruptions of every binary file: a mesh or a "file: byte N:" /
// "file:line:" error, never a crash or a hang (the fuzz target covers this under ASan).
TEST_F(MeshioTest, TruncationsAndCorruptionsNeverCrash) {
  int errors = 0, runs = 0;
  for (const std::string file : {"tet.gmsh22.msh", "hex.gmsh41.msh", "tet.vtk51.vtk",
                                 "hex.vtk42.vtk", "tet.vtk42-float.vtk"}) {
    const std::string text = slurp(path(file));
    ASSERT_FALSE(text.empty()) << file;
    auto check = [&](const std::string& s) {
      ++runs;
      const Result<MeshFile> r = parse_mesh(s, "fuzz.msh");
      if (r.ok()) return;
      ++errors;
      EXPECT_EQ(r.error().rfind("fuzz.msh:", 0), 0u) << r.error();
    };
    for (std::size_t cut = 0; cut < text.size(); ++cut) check(text.substr(0, cut));
    for (std::size_t at = 0; at < text.size(); at += 3) {
      for (const int c : {0x00, 0x01, 0x7f, 0x80, 0xff, 0x0a}) {
        std::string s = text;
        s[at] = static_cast<char>(c);
        check(s);
      }
    }
  }
  // Every truncation before the last section's end line is an error.
  EXPECT_GT(errors, runs / 3);
}

}  // namespace
}  // namespace conica::io
