// Mesh readers: the shared liver meshes, one small geometry in every format, damaged files.
#include "io/mesh_reader.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <string>
#include <string_view>

#include "io/mesh_repair.h"

namespace conica::io {
namespace {

using ::testing::HasSubstr;

// Two unit cubes side by side: [0,1]^3 as one hexahedron (physical 7, "muscle") and
// [1,2]x[0,1]^2 as five positive tetrahedra (physical 3, "liver"), plus one line and one
// triangle. Gmsh node ids are deliberately scattered; nodes are listed in the same order in
// every file, so all formats must give the same Mesh.
constexpr std::string_view kGmsh1 = R"($NOD
12
1000 0 0 0
17 1 0 0
5 1 1 0
999 0 1 0
42 0 0 1
43 1 0 1
44 1 1 1
7 0 1 1
300 2 0 0
301 2 1 0
2 2 0 1
88 2 1 1
$ENDNOD
$ELM
8
1 1 1 1 2 1000 17
2 2 1 1 3 1000 999 5
3 5 7 7 8 1000 17 5 999 42 43 44 7
4 4 3 3 4 17 300 5 43
5 4 3 3 4 300 301 5 88
6 4 3 3 4 300 43 2 88
7 4 3 3 4 5 43 88 44
8 4 3 3 4 300 5 43 88
$ENDELM
)";

constexpr std::string_view kGmsh22 = R"($MeshFormat
2.2 0 8
$EndMeshFormat
$PhysicalNames
3
1 1 "edge"
3 3 "liver"
3 7 "muscle"
$EndPhysicalNames
$Nodes
12
1000 0 0 0
17 1 0 0
5 1 1 0
999 0 1 0
42 0 0 1
43 1 0 1
44 1 1 1
7 0 1 1
300 2 0 0
301 2 1 0
2 2 0 1
88 2 1 1
$EndNodes
$Elements
8
1 1 2 1 1 1000 17
2 2 2 1 2 1000 999 5
3 5 2 7 3 1000 17 5 999 42 43 44 7
4 4 2 3 4 17 300 5 43
5 4 2 3 5 300 301 5 88
6 4 2 3 6 300 43 2 88
7 4 2 3 7 5 43 88 44
8 4 2 3 8 300 5 43 88
$EndElements
)";

constexpr std::string_view kGmsh41 = R"($MeshFormat
4.1 0 8
$EndMeshFormat
$PhysicalNames
3
1 1 "edge"
3 3 "liver"
3 7 "muscle"
$EndPhysicalNames
$Entities
0 1 1 2
1 0 0 0 1 0 0 1 1 0
1 0 0 0 1 1 0 0 0
1 0 0 0 1 1 1 1 7 0
2 1 0 0 2 1 1 1 3 0
$EndEntities
$Nodes
2 12 2 1000
3 1 0 8
1000
17
5
999
42
43
44
7
0 0 0
1 0 0
1 1 0
0 1 0
0 0 1
1 0 1
1 1 1
0 1 1
3 2 0 4
300
301
2
88
2 0 0
2 1 0
2 0 1
2 1 1
$EndNodes
$Elements
4 8 1 8
1 1 1 1
1 1000 17
2 1 2 1
2 1000 999 5
3 1 5 1
3 1000 17 5 999 42 43 44 7
3 2 4 5
4 17 300 5 43
5 300 301 5 88
6 300 43 2 88
7 5 43 88 44
8 300 5 43 88
$EndElements
)";

// Same cells; dataset-level FIELD data and POINT_DATA must be skipped, the integer CELL_DATA
// scalar gives the regions.
constexpr std::string_view kVtk = R"(# vtk DataFile Version 3.0
two cubes
ASCII
DATASET UNSTRUCTURED_GRID
FIELD FieldData 1
TIME 1 1 double
0.5
POINTS 12 double
0 0 0  1 0 0  1 1 0
0 1 0  0 0 1  1 0 1
1 1 1  0 1 1  2 0 0
2 1 0  2 0 1  2 1 1
CELLS 8 41
2 0 1
3 0 3 2
8 0 1 2 3 4 5 6 7
4 1 8 2 5
4 8 9 2 11
4 8 5 10 11
4 2 5 11 6
4 8 2 5 11
CELL_TYPES 8
3 5 12 10 10 10 10 10
POINT_DATA 12
SCALARS temperature float 1
LOOKUP_TABLE default
0 1 2 3 4 5 6 7 8 9 10 11
CELL_DATA 8
SCALARS region int 1
LOOKUP_TABLE default
1 1 7 3 3 3 3 3
VECTORS flow float
0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0
)";

// VTK 5.1 layout: OFFSETS and CONNECTIVITY instead of counted cells.
constexpr std::string_view kVtk51 = R"(# vtk DataFile Version 5.1
two cubes
ASCII
DATASET UNSTRUCTURED_GRID
POINTS 12 float
0 0 0 1 0 0 1 1 0 0 1 0 0 0 1 1 0 1 1 1 1 0 1 1 2 0 0 2 1 0 2 0 1 2 1 1
CELLS 9 33
OFFSETS vtktypeint64
0 2 5 13 17 21 25 29 33
CONNECTIVITY vtktypeint64
0 1  0 3 2  0 1 2 3 4 5 6 7  1 8 2 5  8 9 2 11  8 5 10 11  2 5 11 6  8 2 5 11
CELL_TYPES 8
3 5 12 10 10 10 10 10
CELL_DATA 8
SCALARS region int
LOOKUP_TABLE default
1 1 7 3 3 3 3 3
)";

// 1-based number of the first line of `text` equal to `line`: where an error must point.
int line_of(std::string_view text, std::string_view line) {
  int n = 1;
  std::size_t start = 0;
  while (start <= text.size()) {
    const std::size_t end = std::min(text.find('\n', start), text.size());
    if (text.substr(start, end - start) == line) return n;
    ++n;
    start = end + 1;
  }
  ADD_FAILURE() << "no line '" << line << "'";
  return -1;
}

int count_lines(std::string_view text) {
  int n = 0;
  for (const char c : text) n += c == '\n';
  return text.empty() || text.back() == '\n' ? n : n + 1;
}

std::string replace(std::string_view text, std::string_view from, std::string_view to) {
  std::string s(text);
  const std::size_t at = s.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at != std::string::npos) s.replace(at, from.size(), to);
  return s;
}

// The parse must fail with "name:line: ..." containing `what`.
void expect_error(std::string_view text, int line, std::string_view what,
                  const std::string& name = "bad.msh") {
  const Result<MeshFile> r = parse_mesh(text, name);
  ASSERT_FALSE(r.ok()) << "parsed a damaged file";
  EXPECT_THAT(r.error(), HasSubstr(name + ":" + std::to_string(line) + ": "));
  EXPECT_THAT(r.error(), HasSubstr(std::string(what)));
}

MeshFile parse_ok(std::string_view text, const std::string& name) {
  Result<MeshFile> r = parse_mesh(text, name);
  EXPECT_TRUE(r.ok()) << (r.ok() ? "" : r.error());
  return r.ok() ? std::move(r).value() : MeshFile{};
}

const Region* find_region(const Mesh& m, int id) {
  for (const Region& r : m.regions) {
    if (r.id == id) return &r;
  }
  return nullptr;
}

// ---- the shared SOFA livers ------------------------------------------------------------------

TEST(MeshReader, Liver2FromSofaHasItsKnownCounts) {
  const Result<MeshFile> r = read_mesh(CONICA_SHARED_DIR "/data/meshes/liver2.msh");
  ASSERT_TRUE(r.ok()) << r.error();
  const MeshFile& f = r.value();
  EXPECT_EQ(f.format, "gmsh 1");
  EXPECT_EQ(f.mesh.nodes.size(), 507u);
  EXPECT_EQ(f.mesh.tetrahedra.size(), 1493u);
  EXPECT_EQ(f.mesh.triangles.size(), 860u);
  EXPECT_EQ(f.mesh.hexahedra.size(), 0u);
  EXPECT_EQ(f.skipped_elements, 71);
  EXPECT_EQ(f.skipped_types.at("line"), 71);
  // First node line of the file: "2 0.3708951229648599 -0.4656592203247305 -0.1604279814553062".
  EXPECT_DOUBLE_EQ(f.mesh.nodes[0].x(), 0.3708951229648599);
  EXPECT_DOUBLE_EQ(f.mesh.nodes[0].z(), -0.1604279814553062);
  ASSERT_EQ(f.mesh.regions.size(), 1u);
  EXPECT_EQ(f.mesh.regions[0].id, 2);
  EXPECT_EQ(f.mesh.regions[0].name, "region_2");
  EXPECT_EQ(f.mesh.regions[0].tetrahedra.size(), 1493u);
}

TEST(MeshReader, LiverFromSofaHasItsKnownCounts) {
  const Result<MeshFile> r = read_mesh(CONICA_SHARED_DIR "/data/meshes/liver.msh");
  ASSERT_TRUE(r.ok()) << r.error();
  EXPECT_EQ(r.value().mesh.nodes.size(), 181u);
  EXPECT_EQ(r.value().mesh.tetrahedra.size(), 596u);
  EXPECT_EQ(r.value().skipped_elements, 0);
}

TEST(MeshReader, MissingFileIsAnErrorNamingIt) {
  const Result<MeshFile> r = read_mesh("/nonexistent/dir/none.msh");
  ASSERT_FALSE(r.ok());
  EXPECT_THAT(r.error(), HasSubstr("/nonexistent/dir/none.msh"));
}

// ---- one geometry, four formats --------------------------------------------------------------

void expect_two_cubes(const MeshFile& f) {
  const Mesh& m = f.mesh;
  ASSERT_EQ(m.nodes.size(), 12u);
  EXPECT_EQ(m.nodes[0], Vec3(0, 0, 0));
  EXPECT_EQ(m.nodes[6], Vec3(1, 1, 1));
  EXPECT_EQ(m.nodes[11], Vec3(2, 1, 1));
  ASSERT_EQ(m.hexahedra.size(), 1u);
  EXPECT_EQ(m.hexahedra[0], (std::array<int, 8>{0, 1, 2, 3, 4, 5, 6, 7}));
  ASSERT_EQ(m.tetrahedra.size(), 5u);
  EXPECT_EQ(m.tetrahedra[0], (std::array<int, 4>{1, 8, 2, 5}));
  EXPECT_EQ(m.tetrahedra[4], (std::array<int, 4>{8, 2, 5, 11}));
  ASSERT_EQ(m.triangles.size(), 1u);
  EXPECT_EQ(m.triangles[0], (std::array<int, 3>{0, 3, 2}));
  EXPECT_EQ(f.skipped_elements, 1);
  EXPECT_EQ(f.skipped_types.at("line"), 1);
  ASSERT_EQ(m.regions.size(), 2u);
  const Region* liver = find_region(m, 3);
  const Region* muscle = find_region(m, 7);
  ASSERT_TRUE(liver && muscle);
  EXPECT_EQ(liver->tetrahedra, (std::vector<int>{0, 1, 2, 3, 4}));
  EXPECT_TRUE(liver->hexahedra.empty());
  EXPECT_EQ(muscle->hexahedra, (std::vector<int>{0}));
  EXPECT_TRUE(muscle->tetrahedra.empty());
  // Two unit cubes, every element positive: nothing to repair.
  EXPECT_NEAR(total_volume(m), 2.0, 1e-12);
  EXPECT_TRUE(inspect(m).clean()) << to_string(inspect(m));
}

TEST(MeshReader, Gmsh1TwoCubes) {
  const MeshFile f = parse_ok(kGmsh1, "cubes.msh");
  EXPECT_EQ(f.format, "gmsh 1");
  expect_two_cubes(f);
  EXPECT_EQ(find_region(f.mesh, 3)->name, "region_3");
}

TEST(MeshReader, Gmsh22TwoCubesWithPhysicalNames) {
  const MeshFile f = parse_ok(kGmsh22, "cubes.msh");
  EXPECT_EQ(f.format, "gmsh 2.2");
  expect_two_cubes(f);
  EXPECT_EQ(find_region(f.mesh, 3)->name, "liver");
  EXPECT_EQ(find_region(f.mesh, 7)->name, "muscle");
}

TEST(MeshReader, Gmsh41TwoCubesWithEntityPhysicalGroupsAndAHex) {
  const MeshFile f = parse_ok(kGmsh41, "cubes.msh");
  EXPECT_EQ(f.format, "gmsh 4.1");
  expect_two_cubes(f);
  EXPECT_EQ(find_region(f.mesh, 3)->name, "liver");
  EXPECT_EQ(find_region(f.mesh, 7)->name, "muscle");
}

TEST(MeshReader, VtkTwoCubesWithCellDataRegions) {
  const MeshFile f = parse_ok(kVtk, "cubes.vtk");
  EXPECT_EQ(f.format, "vtk 3.0");
  expect_two_cubes(f);
  EXPECT_EQ(find_region(f.mesh, 7)->name, "region_7");
}

TEST(MeshReader, Vtk51OffsetsLayoutTwoCubes) {
  const MeshFile f = parse_ok(kVtk51, "cubes.vtk");
  EXPECT_EQ(f.format, "vtk 5.1");
  expect_two_cubes(f);
}

TEST(MeshReader, AllFormatsGiveTheSameMesh) {
  const Mesh a = parse_ok(kGmsh1, "a").mesh;
  for (const std::string_view text : {kGmsh22, kGmsh41, kVtk, kVtk51}) {
    const Mesh b = parse_ok(text, "b").mesh;
    EXPECT_EQ(a.nodes, b.nodes);
    EXPECT_EQ(a.tetrahedra, b.tetrahedra);
    EXPECT_EQ(a.hexahedra, b.hexahedra);
    EXPECT_EQ(a.triangles, b.triangles);
    ASSERT_EQ(a.regions.size(), b.regions.size());
    for (std::size_t i = 0; i < a.regions.size(); ++i) {
      EXPECT_EQ(a.regions[i].id, b.regions[i].id);
      EXPECT_EQ(a.regions[i].tetrahedra, b.regions[i].tetrahedra);
      EXPECT_EQ(a.regions[i].hexahedra, b.regions[i].hexahedra);
    }
  }
}

TEST(MeshReader, FormatComesFromContentNotExtension) {
  EXPECT_EQ(parse_ok(kVtk, "cubes.msh").format, "vtk 3.0");
  EXPECT_EQ(parse_ok(kGmsh41, "cubes.vtk").format, "gmsh 4.1");
}

TEST(MeshReader, WindowsLineEndingsAndBlankLinesAreAccepted) {
  std::string crlf;
  for (const char c : kGmsh22) {
    if (c == '\n')
      crlf += "\r\n\r\n";
    else
      crlf += c;
  }
  expect_two_cubes(parse_ok(crlf, "crlf.msh"));
}

// ---- damaged files: every error names file:line and the problem ----------------------------

TEST(MeshReaderErrors, TruncatedFile) {
  // Cut after the 4th element line of $Elements.
  const std::string_view cut = "4 4 2 3 4 17 300 5 43\n";
  const std::string text(kGmsh22.substr(0, kGmsh22.find(cut) + cut.size()));
  expect_error(text, count_lines(text), "unexpected end of file in $Elements after 4 of 8");
}

TEST(MeshReaderErrors, TruncatedMidLine) {
  const std::string_view cut = "4 4 2 3 4 17 300";
  const std::string text(kGmsh22.substr(0, kGmsh22.find(cut) + cut.size()));
  expect_error(text, count_lines(text), "element 4 (tetrahedron) has 2 nodes, expected 4");
}

TEST(MeshReaderErrors, MissingSectionEnd) {
  const std::string text = replace(kGmsh22, "$EndNodes\n", "");
  expect_error(text, line_of(text, "$Elements"), "expected $EndNodes after 12 nodes");
  const std::string no_end = replace(kGmsh22, "$EndElements\n", "");
  expect_error(no_end, count_lines(no_end), "missing $EndElements");
  const std::string v1 = replace(kGmsh1, "$ENDNOD\n", "");
  expect_error(v1, line_of(v1, "$ELM"), "expected $ENDNOD");
  const std::string skipped = std::string(kGmsh22) + "$Comments\nhello\n";
  expect_error(skipped, line_of(skipped, "$Comments"), "section $Comments has no $EndComments");
}

TEST(MeshReaderErrors, BadNumber) {
  const std::string text = replace(kGmsh22, "43 1 0 1\n", "43 1 0.5x 1\n");
  expect_error(text, line_of(text, "43 1 0.5x 1"), "'0.5x' is not a finite number");
  const std::string nan = replace(kGmsh22, "43 1 0 1\n", "43 1 nan 1\n");
  expect_error(nan, line_of(nan, "43 1 nan 1"), "'nan' is not a finite number");
  const std::string count = replace(kGmsh22, "$Nodes\n12\n", "$Nodes\ntwelve\n");
  expect_error(count, line_of(count, "twelve"), "node count: 'twelve' is not an integer");
  const std::string vtk = replace(kVtk, "1 1 1  0 1 1", "1 1 1  0 1 e");
  expect_error(vtk, line_of(vtk, "1 1 1  0 1 e  2 0 0"), "'e' is not a finite number", "bad.vtk");
}

TEST(MeshReaderErrors, UnknownNodeReference) {
  const std::string text = replace(kGmsh22, "7 4 2 3 7 5 43 88 44", "37 4 2 3 7 5 43 9001 44");
  expect_error(text, line_of(text, "37 4 2 3 7 5 43 9001 44"),
               "element 37 references unknown node 9001");
  const std::string v1 = replace(kGmsh1, "7 4 3 3 4 5 43 88 44", "7 4 3 3 4 5 43 88 4");
  expect_error(v1, line_of(v1, "7 4 3 3 4 5 43 88 4"), "element 7 references unknown node 4");
  const std::string v4 = replace(kGmsh41, "6 300 43 2 88", "6 300 43 3 88");
  expect_error(v4, line_of(v4, "6 300 43 3 88"), "element 6 references unknown node 3");
  const std::string vtk = replace(kVtk, "4 8 9 2 11", "4 8 9 2 12");
  expect_error(vtk, line_of(vtk, "4 8 9 2 12"), "cell 4 references unknown point 12", "bad.vtk");
}

TEST(MeshReaderErrors, DuplicateNodeId) {
  const std::string text = replace(kGmsh22, "301 2 1 0", "300 2 1 0");
  expect_error(text, line_of(text, "300 2 1 0"), "node 300 is defined twice");
}

TEST(MeshReaderErrors, CountMismatch) {
  const std::string more = replace(kGmsh22, "$Nodes\n12\n", "$Nodes\n13\n");
  expect_error(more, line_of(more, "$EndNodes"), "after 12 of 13 nodes: the count does not match");
  const std::string fewer = replace(kGmsh22, "$Elements\n8\n", "$Elements\n7\n");
  expect_error(fewer, line_of(fewer, "8 4 2 3 8 300 5 43 88"), "expected $EndElements");
  const std::string v1 = replace(kGmsh1, "4 4 3 3 4 17 300 5 43", "4 4 3 3 3 17 300 5");
  expect_error(v1, line_of(v1, "4 4 3 3 3 17 300 5"), "has 3 nodes, expected 4");
  const std::string v4 = replace(kGmsh41, "4 8 1 8\n", "4 9 1 8\n");
  expect_error(v4, line_of(v4, "4 9 1 8"), "element blocks hold 8 elements, header announced 9");
  const std::string block = replace(kGmsh41, "3 2 0 4\n", "3 2 0 5\n");
  expect_error(block, line_of(block, "3 2 0 5"), "node blocks hold more than the 12 nodes");
  const std::string types = replace(kVtk, "CELL_TYPES 8", "CELL_TYPES 7");
  expect_error(types, line_of(types, "CELL_TYPES 7"), "CELL_TYPES has 7 entries for 8 cells",
               "bad.vtk");
  const std::string data = replace(kVtk, "CELL_DATA 8", "CELL_DATA 9");
  expect_error(data, line_of(data, "CELL_DATA 9"), "CELL_DATA has 9 values for 8 cells", "bad.vtk");
  const std::string cells = replace(kVtk, "CELLS 8 41", "CELLS 8 40");
  expect_error(cells, line_of(cells, "4 8 2 5 11"), "overflows the cell list size 40", "bad.vtk");
}

TEST(MeshReaderErrors, UnsupportedVersionOrBinary) {
  const std::string v3 = replace(kGmsh22, "2.2 0 8", "3.0 0 8");
  expect_error(v3, 2, "unsupported Gmsh version 3.0");
  const std::string v40 = replace(kGmsh41, "4.1 0 8", "4 0 8");
  expect_error(v40, 2, "unsupported Gmsh version 4");
  // Binary files are read (tests/io/meshio_test.cc); an ASCII file that says it is binary
  // fails where the binary data would begin, naming the byte offset.
  const std::string binary = replace(kGmsh41, "4.1 0 8", "4.1 1 8");
  const Result<MeshFile> b = parse_mesh(binary, "bad.msh");
  ASSERT_FALSE(b.ok());
  EXPECT_THAT(b.error(), HasSubstr("bad.msh: byte 20: endianness marker: expected the integer 1"));
  expect_error(replace(kGmsh41, "4.1 0 8", "4.1 2 8"), 2, "file type 2 is neither 0 (ASCII)");
  const Result<MeshFile> v = parse_mesh(replace(kVtk, "ASCII", "BINARY"), "bad.vtk");
  ASSERT_FALSE(v.ok());
  EXPECT_THAT(v.error(), HasSubstr("bad.vtk: byte "));
  const std::string grid = replace(kVtk, "UNSTRUCTURED_GRID", "STRUCTURED_POINTS");
  expect_error(grid, 4, "unsupported VTK dataset STRUCTURED_POINTS", "bad.vtk");
  expect_error("solid cube\nfacet normal 0 0 1\n", 1, "unrecognised mesh format", "cube.stl");
  expect_error("<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\">\n", 1,
               "XML mesh files (VTK .vtu/.vtk XML, XDMF...) are not supported; convert it with "
               "`meshio convert --output-format gmsh22 in.vtu in.msh`",
               "in.vtu");
  expect_error("", 1, "empty file", "empty.msh");
  expect_error("\n\n  \n", 1, "empty file", "empty.msh");
}

TEST(MeshReaderErrors, HugeCountsFailWithoutAllocating) {
  // A header claiming 10^12 nodes in a file of a few hundred bytes fails at once.
  const std::string v2 = replace(kGmsh22, "$Nodes\n12\n", "$Nodes\n1000000000000\n");
  expect_error(v2, line_of(v2, "1000000000000"), "node count 1000000000000 is more than");
  const std::string v1 = replace(kGmsh1, "$ELM\n8\n", "$ELM\n999999999999999\n");
  expect_error(v1, line_of(v1, "999999999999999"), "element count 999999999999999 is more");
  const std::string v4 = replace(kGmsh41, "2 12 2 1000\n", "2 1000000000000 2 1000\n");
  expect_error(v4, line_of(v4, "2 1000000000000 2 1000"), "node count 1000000000000 is more");
  const std::string vtk = replace(kVtk, "POINTS 12 double", "POINTS 1000000000000 double");
  expect_error(vtk, line_of(vtk, "POINTS 1000000000000 double"), "point count", "bad.vtk");
  const std::string negative = replace(kGmsh22, "$Nodes\n12\n", "$Nodes\n-3\n");
  expect_error(negative, line_of(negative, "-3"), "node count is negative");
  const std::string overflow = replace(kGmsh22, "$Nodes\n12\n", "$Nodes\n99999999999999999999\n");
  expect_error(overflow, line_of(overflow, "99999999999999999999"), "is not an integer");
}

// Every prefix and many one-byte corruptions of every format: parsing returns a mesh or a
// "file:line:" error, never crashes or hangs (run under CONICA_SANITIZE for memory errors).
TEST(MeshReaderErrors, TruncationsAndCorruptionsNeverCrash) {
  int errors = 0;
  for (const std::string_view text : {kGmsh1, kGmsh22, kGmsh41, kVtk, kVtk51}) {
    auto check = [&errors](const std::string& s) {
      const Result<MeshFile> r = parse_mesh(s, "fuzz.msh");
      if (r.ok()) return;
      ++errors;
      EXPECT_EQ(r.error().rfind("fuzz.msh:", 0), 0u) << r.error();
    };
    for (std::size_t cut = 0; cut < text.size(); ++cut) check(std::string(text.substr(0, cut)));
    for (std::size_t at = 0; at < text.size(); ++at) {
      for (const char c : {'9', '-', '$', ' ', '\n', 'x', '\0'}) {
        std::string s(text);
        s[at] = c;
        check(s);
      }
    }
  }
  EXPECT_GT(errors, 1000);  // the corruptions are mostly caught, not silently accepted
}

}  // namespace
}  // namespace conica::io
