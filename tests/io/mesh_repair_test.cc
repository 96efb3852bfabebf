// Degenerate meshes and their repair; spring pairs and surface extraction.
#include "io/mesh_repair.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <set>

#include "io/mesh_reader.h"

namespace conica::io {
namespace {

// Unit cube corners in VTK order.
std::vector<Vec3> cube_nodes(const Vec3& offset = Vec3::Zero()) {
  std::vector<Vec3> x = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0},
                         {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};
  for (Vec3& p : x) p += offset;
  return x;
}

// The unit cube as five positive tetrahedra (four corners and a central one).
Mesh five_tet_cube() {
  Mesh m;
  m.nodes = cube_nodes();
  m.tetrahedra = {{0, 1, 3, 4}, {1, 2, 3, 6}, {1, 4, 5, 6}, {3, 4, 6, 7}, {1, 3, 4, 6}};
  return m;
}

Mesh one_tet() {
  Mesh m;
  m.nodes = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  m.tetrahedra = {{0, 1, 2, 3}};
  return m;
}

Vec3 tet_centroid(const Mesh& m, const std::array<int, 4>& t) {
  return (m.nodes[t[0]] + m.nodes[t[1]] + m.nodes[t[2]] + m.nodes[t[3]]) / 4.0;
}

Vec3 normal(const Mesh& m, const std::array<int, 3>& f) {
  return (m.nodes[f[1]] - m.nodes[f[0]]).cross(m.nodes[f[2]] - m.nodes[f[0]]);
}

// Volume enclosed by a closed triangle surface (divergence theorem): sum p0 . (p1 x p2) / 6.
double enclosed_volume(const Mesh& m, const std::vector<std::array<int, 3>>& surface) {
  double v = 0;
  for (const auto& f : surface) {
    v += m.nodes[f[0]].dot(m.nodes[f[1]].cross(m.nodes[f[2]])) / 6.0;
  }
  return v;
}

// ---- volumes -------------------------------------------------------------------------------

TEST(MeshGeometry, TetVolumeSignFollowsOrientation) {
  const Mesh m = one_tet();
  EXPECT_DOUBLE_EQ(tet_volume(m.nodes[0], m.nodes[1], m.nodes[2], m.nodes[3]), 1.0 / 6.0);
  EXPECT_DOUBLE_EQ(tet_volume(m.nodes[0], m.nodes[2], m.nodes[1], m.nodes[3]), -1.0 / 6.0);
}

TEST(MeshGeometry, HexVolumeIsExactForTrilinearHexes) {
  std::array<Vec3, 8> x;
  std::vector<Vec3> c = cube_nodes();
  // A 2 x 3 x 0.5 box.
  for (int i = 0; i < 8; ++i) x[i] = c[i].cwiseProduct(Vec3(2, 3, 0.5));
  EXPECT_NEAR(hex_volume(x), 3.0, 1e-14);
  // Raise one top corner to z = 2: the top is z = 1 + u v, so V = 1 + 1/4.
  for (int i = 0; i < 8; ++i) x[i] = c[i];
  x[6].z() = 2;
  EXPECT_NEAR(hex_volume(x), 1.25, 1e-14);
  // Top and bottom swapped: the same volume, negative.
  const std::array<Vec3, 8> y = {c[4], c[5], c[6], c[7], c[0], c[1], c[2], c[3]};
  EXPECT_NEAR(hex_volume(y), -1.0, 1e-14);
}

TEST(MeshGeometry, FiveTetCubeHasUnitVolumeAndKnownBox) {
  const Mesh m = five_tet_cube();
  EXPECT_NEAR(total_volume(m), 1.0, 1e-14);
  const BoundingBox b = bounding_box(m);
  EXPECT_EQ(b.min, Vec3(0, 0, 0));
  EXPECT_EQ(b.max, Vec3(1, 1, 1));
}

// ---- springs and surface -------------------------------------------------------------------

TEST(MeshTopology, UniqueEdgesOfFiveTetCube) {
  // 12 cube edges + 6 face diagonals.
  const auto edges = unique_edges(five_tet_cube());
  EXPECT_EQ(edges.size(), 18u);
  for (const auto& e : edges) EXPECT_LT(e[0], e[1]);
  EXPECT_TRUE(std::is_sorted(edges.begin(), edges.end()));
}

TEST(MeshTopology, HexSpringsAreAllPairsOfTheCube) {
  Mesh m;
  m.nodes = cube_nodes();
  std::vector<Vec3> right = cube_nodes(Vec3(1, 0, 0));
  // Second cube shares the face x = 1 (nodes 1, 2, 5, 6); new nodes 8..11.
  m.nodes.insert(m.nodes.end(), {right[1], right[2], right[5], right[6]});
  m.hexahedra = {{0, 1, 2, 3, 4, 5, 6, 7}};
  EXPECT_EQ(spring_pairs(m).size(), 28u);  // 12 edges + 12 face + 4 body diagonals
  EXPECT_TRUE(unique_edges(m).empty());    // tetrahedra only
  m.hexahedra.push_back({1, 8, 9, 2, 5, 10, 11, 6});
  EXPECT_EQ(spring_pairs(m).size(), 28u * 2 - 6);  // the shared face's 6 pairs once
}

TEST(MeshTopology, SurfaceOfOneTetIsOutward) {
  const Mesh m = one_tet();
  const auto s = surface_triangles(m);
  ASSERT_EQ(s.size(), 4u);
  const Vec3 c = tet_centroid(m, m.tetrahedra[0]);
  for (const auto& f : s) {
    const Vec3 mid = (m.nodes[f[0]] + m.nodes[f[1]] + m.nodes[f[2]]) / 3.0;
    EXPECT_GT(normal(m, f).dot(mid - c), 0);
  }
  EXPECT_NEAR(enclosed_volume(m, s), 1.0 / 6.0, 1e-15);
}

TEST(MeshTopology, SurfaceOfFiveTetCubeIsItsTwelveOutwardHalfFaces) {
  const Mesh m = five_tet_cube();
  const auto s = surface_triangles(m);
  ASSERT_EQ(s.size(), 12u);
  double area = 0;
  for (const auto& f : s) {
    const Vec3 mid = (m.nodes[f[0]] + m.nodes[f[1]] + m.nodes[f[2]]) / 3.0;
    EXPECT_GT(normal(m, f).dot(mid - Vec3(0.5, 0.5, 0.5)), 0);
    area += normal(m, f).norm() / 2;
  }
  EXPECT_NEAR(area, 6.0, 1e-14);
  EXPECT_NEAR(enclosed_volume(m, s), 1.0, 1e-14);
}

// ---- the liver -----------------------------------------------------------------------------

TEST(MeshRepair, Liver2IsCleanAndItsSurfaceIsTheFileSurface) {
  Result<MeshFile> r = read_mesh(CONICA_SHARED_DIR "/data/meshes/liver2.msh");
  ASSERT_TRUE(r.ok()) << r.error();
  Mesh m = std::move(r).value().mesh;
  const std::vector<std::array<int, 3>> file_surface = m.triangles;
  const MeshReport report = repair(m);
  EXPECT_TRUE(report.clean()) << to_string(report);
  EXPECT_EQ(m.nodes.size(), 507u);
  EXPECT_EQ(m.tetrahedra.size(), 1493u);
  for (const auto& t : m.tetrahedra) {
    EXPECT_GT(tet_volume(m.nodes[t[0]], m.nodes[t[1]], m.nodes[t[2]], m.nodes[t[3]]), 0);
  }
  const double volume = total_volume(m);
  EXPECT_GT(volume, 0);

  // The extracted surface is the 860 triangles the file lists, as unordered node sets.
  const auto surface = surface_triangles(m);
  auto as_set = [](const std::vector<std::array<int, 3>>& tris) {
    std::set<std::array<int, 3>> s;
    for (auto t : tris) {
      std::sort(t.begin(), t.end());
      s.insert(t);
    }
    return s;
  };
  EXPECT_EQ(surface.size(), 860u);
  EXPECT_EQ(as_set(surface), as_set(file_surface));
  // Outward: the enclosed volume equals the tet volume; closed and consistently oriented:
  // each directed edge appears once and its reverse once.
  EXPECT_NEAR(enclosed_volume(m, surface), volume, 1e-9 * volume);
  std::map<std::array<int, 2>, int> directed;
  for (const auto& f : surface) {
    for (int k = 0; k < 3; ++k) ++directed[{f[k], f[(k + 1) % 3]}];
  }
  for (const auto& [e, n] : directed) {
    EXPECT_EQ(n, 1);
    EXPECT_EQ(directed.count({e[1], e[0]}), 1u);
  }
  // A solid ball: V - E + F - T = 1, with F = (4 T + boundary faces) / 2.
  const long V = 507, E = static_cast<long>(unique_edges(m).size()), T = 1493;
  const long F = (4 * T + 860) / 2;
  EXPECT_EQ(V - E + F - T, 1);
}

// ---- degenerate input ----------------------------------------------------------------------

TEST(MeshRepair, MergesDuplicateNodesWithinRelativeTolerance) {
  // Two tets sharing face (1, 2, 3); the second lists its own copies of the face nodes, one
  // of them 1e-13 away (bbox diagonal sqrt 3): duplicates. Node 8 is 1e-3 away: distinct.
  Mesh m;
  m.nodes = {{0, 0, 0}, {1, 0, 0},         {0, 1, 0}, {0, 0, 1},    {1, 1, 1},
             {1, 0, 0}, {0, 1 + 1e-13, 0}, {0, 0, 1}, {0, 0, 1.001}};
  m.tetrahedra = {{0, 1, 2, 3}, {4, 7, 6, 5}};
  m.triangles = {{5, 6, 8}};
  const MeshReport r = repair(m);
  EXPECT_EQ(r.duplicate_nodes, 3);
  EXPECT_EQ(r.unreferenced_nodes, 0);
  EXPECT_EQ(r.inverted_tetrahedra, 0);
  ASSERT_EQ(m.nodes.size(), 6u);  // 0..4 and the far node
  EXPECT_EQ(m.tetrahedra[1], (std::array<int, 4>{4, 3, 2, 1}));
  EXPECT_EQ(m.triangles[0], (std::array<int, 3>{1, 2, 5}));
  EXPECT_EQ(m.nodes[5], Vec3(0, 0, 1.001));
  EXPECT_EQ(unique_edges(m).size(), 9u);  // 6 + 6 - 3 shared
  EXPECT_EQ(surface_triangles(m).size(), 6u);
}

TEST(MeshRepair, FlipsInvertedTetrahedra) {
  Mesh m = five_tet_cube();
  std::swap(m.tetrahedra[2][0], m.tetrahedra[2][1]);
  std::swap(m.tetrahedra[4][2], m.tetrahedra[4][3]);
  EXPECT_NEAR(total_volume(m), 1.0 - 2 * (1.0 / 6 + 1.0 / 3), 1e-14);
  const MeshReport r = repair(m);
  EXPECT_EQ(r.inverted_tetrahedra, 2);
  EXPECT_EQ(m.tetrahedra.size(), 5u);
  EXPECT_NEAR(total_volume(m), 1.0, 1e-14);
  for (const auto& t : m.tetrahedra) {
    EXPECT_GT(tet_volume(m.nodes[t[0]], m.nodes[t[1]], m.nodes[t[2]], m.nodes[t[3]]), 0);
  }
  EXPECT_TRUE(inspect(m).clean());  // repair is idempotent
}

TEST(MeshRepair, DropsFlatAndRepeatedNodeElementsAndRemapsRegions) {
  Mesh m = five_tet_cube();
  m.tetrahedra.insert(m.tetrahedra.begin() + 1, {0, 1, 2, 3});  // bottom face: flat
  m.tetrahedra.push_back({0, 1, 1, 7});                         // repeats node 1
  m.regions = {{"all", 1, {0, 1, 2, 3, 4, 5, 6}, {}}, {"flat", 2, {1}, {}}};
  const MeshReport r = repair(m);
  EXPECT_EQ(r.zero_volume_tetrahedra, 1);
  EXPECT_EQ(r.repeated_node_elements, 1);
  ASSERT_EQ(m.tetrahedra.size(), 5u);
  EXPECT_EQ(m.tetrahedra[1], (std::array<int, 4>{1, 2, 3, 6}));
  EXPECT_EQ(m.regions[0].tetrahedra, (std::vector<int>{0, 1, 2, 3, 4}));
  EXPECT_TRUE(m.regions[1].tetrahedra.empty());
  EXPECT_NEAR(total_volume(m), 1.0, 1e-14);
}

TEST(MeshRepair, NearlyFlatSliverIsKeptAboveTolerance) {
  Mesh m = one_tet();
  m.nodes[3] = Vec3(0.2, 0.2, 1e-6);  // volume 1e-6 / 6 of a unit-size tet
  EXPECT_EQ(inspect(m).zero_volume_tetrahedra, 0);
  m.nodes[3] = Vec3(0.2, 0.2, 1e-12);
  EXPECT_EQ(inspect(m).zero_volume_tetrahedra, 1);
}

TEST(MeshRepair, DropsUnreferencedNodesAndRemapsIndices) {
  Mesh m = one_tet();
  m.nodes.insert(m.nodes.begin(), Vec3(5, 5, 5));  // unused, at index 0
  m.nodes.push_back(Vec3(7, 7, 7));                // unused, at the end
  m.tetrahedra = {{1, 2, 3, 4}};
  const MeshReport r = repair(m);
  EXPECT_EQ(r.unreferenced_nodes, 2);
  ASSERT_EQ(m.nodes.size(), 4u);
  EXPECT_EQ(m.tetrahedra[0], (std::array<int, 4>{0, 1, 2, 3}));
  EXPECT_EQ(m.nodes[1], Vec3(1, 0, 0));
}

TEST(MeshRepair, HexahedraInvertedFlatAndDistorted) {
  Mesh m;
  m.nodes = cube_nodes();
  const std::vector<Vec3> flat = {{3, 0, 0}, {4, 0, 0}, {4, 1, 0}, {3, 1, 0}};
  m.nodes.insert(m.nodes.end(), flat.begin(), flat.end());  // 8..11, all at z = 0
  m.hexahedra = {{4, 5, 6, 7, 0, 1, 2, 3},                  // inverted
                 {8, 9, 10, 11, 8, 9, 10, 11}};             // repeats nodes
  m.hexahedra.push_back({8, 9, 10, 11, 0, 0, 0, 0});
  Mesh flat_hex;
  flat_hex.nodes = cube_nodes();
  for (int i = 0; i < 8; ++i) {  // the top slid sideways onto the bottom: no volume
    flat_hex.nodes[i].z() = 0;
    if (i >= 4) flat_hex.nodes[i] += Vec3(0.01 * (i - 3), 0.005, 0);
  }
  flat_hex.hexahedra = {{0, 1, 2, 3, 4, 5, 6, 7}};

  const MeshReport r = repair(m);
  EXPECT_EQ(r.inverted_hexahedra, 1);
  EXPECT_EQ(r.repeated_node_elements, 2);
  ASSERT_EQ(m.hexahedra.size(), 1u);
  EXPECT_EQ(m.hexahedra[0], (std::array<int, 8>{0, 1, 2, 3, 4, 5, 6, 7}));
  EXPECT_NEAR(total_volume(m), 1.0, 1e-14);
  EXPECT_EQ(m.nodes.size(), 8u);

  const MeshReport rf = repair(flat_hex);
  EXPECT_EQ(rf.zero_volume_hexahedra, 1);
  EXPECT_TRUE(flat_hex.hexahedra.empty());
  EXPECT_TRUE(flat_hex.nodes.empty());

  // Corner 6 pushed inside towards corner 0: positive volume, negative Jacobian at corner 6.
  Mesh bent;
  bent.nodes = cube_nodes();
  bent.nodes[6] = Vec3(0.2, 0.2, 0.2);
  bent.hexahedra = {{0, 1, 2, 3, 4, 5, 6, 7}};
  const MeshReport rb = repair(bent);
  EXPECT_EQ(rb.distorted_hexahedra, 1);
  EXPECT_EQ(bent.hexahedra.size(), 1u);
}

TEST(MeshRepair, NeverCrashesOnNonsense) {
  Mesh empty;
  EXPECT_TRUE(repair(empty).clean());

  Mesh bad = one_tet();
  bad.tetrahedra.push_back({0, 1, 2, 99});
  bad.tetrahedra.push_back({-1, 1, 2, 3});
  bad.hexahedra.push_back({0, 1, 2, 3, 4, 5, 6, 1000});
  bad.triangles = {{0, 1, 7}, {0, 1, 1}, {0, 1, 2}};
  bad.regions = {{"r", 1, {0, 1, 2, 57}, {0, -4}}};
  const MeshReport r = repair(bad);
  EXPECT_EQ(r.bad_index_elements, 3);
  EXPECT_EQ(r.degenerate_triangles, 2);
  EXPECT_EQ(bad.tetrahedra.size(), 1u);
  EXPECT_EQ(bad.triangles.size(), 1u);
  EXPECT_EQ(bad.regions[0].tetrahedra, (std::vector<int>{0}));
  EXPECT_TRUE(bad.regions[0].hexahedra.empty());

  Mesh nan = one_tet();
  nan.nodes[3].z() = std::numeric_limits<double>::quiet_NaN();
  const MeshReport rn = repair(nan);
  EXPECT_EQ(rn.zero_volume_tetrahedra, 1);
  EXPECT_TRUE(nan.nodes.empty());

  // Every node at one point: the bounding box is empty, merging is exact.
  Mesh point;
  point.nodes.assign(4, Vec3(1, 2, 3));
  point.tetrahedra = {{0, 1, 2, 3}};
  const MeshReport rp = repair(point);
  EXPECT_EQ(rp.duplicate_nodes, 3);
  EXPECT_EQ(rp.repeated_node_elements, 1);
  EXPECT_TRUE(point.nodes.empty());
}

TEST(MeshRepair, ReportTextNamesEachKind) {
  MeshReport r;
  EXPECT_EQ(to_string(r), "clean\n");
  r.duplicate_nodes = 3;
  r.inverted_tetrahedra = 2;
  const std::string s = to_string(r);
  EXPECT_NE(s.find("duplicate nodes (merged): 3"), std::string::npos) << s;
  EXPECT_NE(s.find("inverted tetrahedra (flipped): 2"), std::string::npos) << s;
  EXPECT_EQ(s.find("unreferenced"), std::string::npos) << s;
}

}  // namespace
}  // namespace conica::io
