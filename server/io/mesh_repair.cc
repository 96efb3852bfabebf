#include "io/mesh_repair.h"

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numeric>
#include <tuple>
#include <unordered_map>

namespace conica::io {

namespace {

template <std::size_t N>
bool indices_valid(const std::array<int, N>& e, int num_nodes) {
  return std::all_of(e.begin(), e.end(), [&](int i) { return i >= 0 && i < num_nodes; });
}

template <std::size_t N>
bool repeats_node(std::array<int, N> e) {
  std::sort(e.begin(), e.end());
  return std::adjacent_find(e.begin(), e.end()) != e.end();
}

template <std::size_t N>
double longest_edge(const std::vector<Vec3>& x, const std::array<int, N>& e) {
  double l = 0;
  for (std::size_t i = 0; i < N; ++i) {
    for (std::size_t j = i + 1; j < N; ++j) l = std::max(l, (x[e[i]] - x[e[j]]).norm());
  }
  return l;
}

// Trilinear map of the unit cube: dx/d(u, v, w) at (u, v, w). Corner i sits at
// (u, v, w) = kCorner[i] (VTK order).
constexpr int kCorner[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0},
                               {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};

double hex_jacobian(const std::array<Vec3, 8>& x, double u, const double v, const double w) {
  const double p[3] = {u, v, w};
  Eigen::Matrix3d j = Eigen::Matrix3d::Zero();
  for (int i = 0; i < 8; ++i) {
    double f[3], df[3];  // 1-D shape factor and its derivative along each axis
    for (int a = 0; a < 3; ++a) {
      f[a] = kCorner[i][a] ? p[a] : 1 - p[a];
      df[a] = kCorner[i][a] ? 1 : -1;
    }
    j.col(0) += x[i] * (df[0] * f[1] * f[2]);
    j.col(1) += x[i] * (f[0] * df[1] * f[2]);
    j.col(2) += x[i] * (f[0] * f[1] * df[2]);
  }
  return j.determinant();
}

std::array<Vec3, 8> hex_points(const std::vector<Vec3>& x, const std::array<int, 8>& h) {
  std::array<Vec3, 8> p;
  for (int i = 0; i < 8; ++i) p[i] = x[h[i]];
  return p;
}

// Maps each node to the first node (in index order) within `tol` of it, or to itself.
std::vector<int> duplicate_representatives(const std::vector<Vec3>& x, double tol,
                                           const Vec3& origin) {
  const int n = static_cast<int>(x.size());
  std::vector<int> rep(n);
  std::iota(rep.begin(), rep.end(), 0);
  if (!(tol > 0)) {
    // Exact equality: sort by coordinates, merge equal runs into their smallest index.
    std::vector<int> order;
    for (int i = 0; i < n; ++i) {
      if (x[i].allFinite()) order.push_back(i);
    }
    auto less = [&](int a, int b) {
      return std::tie(x[a].x(), x[a].y(), x[a].z(), a) < std::tie(x[b].x(), x[b].y(), x[b].z(), b);
    };
    std::sort(order.begin(), order.end(), less);
    for (std::size_t k = 1; k < order.size(); ++k) {
      if (x[order[k]] == x[order[k - 1]]) rep[order[k]] = rep[order[k - 1]];
    }
    return rep;
  }
  // Uniform grid of cell size tol: a node's match lies in the 27 cells around it.
  using Key = std::array<std::int64_t, 3>;
  struct KeyHash {
    std::size_t operator()(const Key& k) const {
      return static_cast<std::size_t>(k[0] * 73856093 ^ k[1] * 19349663 ^ k[2] * 83492791);
    }
  };
  std::unordered_map<Key, std::vector<int>, KeyHash> grid;
  for (int i = 0; i < n; ++i) {
    if (!x[i].allFinite()) continue;
    Key key;
    for (int a = 0; a < 3; ++a) {
      key[a] = static_cast<std::int64_t>(std::floor((x[i][a] - origin[a]) / tol));
    }
    int found = -1;
    for (int dx = -1; dx <= 1 && found < 0; ++dx) {
      for (int dy = -1; dy <= 1 && found < 0; ++dy) {
        for (int dz = -1; dz <= 1 && found < 0; ++dz) {
          const auto it = grid.find({key[0] + dx, key[1] + dy, key[2] + dz});
          if (it == grid.end()) continue;
          for (const int j : it->second) {
            if ((x[i] - x[j]).norm() <= tol && (found < 0 || j < found)) found = j;
          }
        }
      }
    }
    if (found >= 0) {
      rep[i] = found;
    } else {
      grid[key].push_back(i);
    }
  }
  return rep;
}

// Keeps the entries of `v` with keep[i] >= 0 and returns old index -> new index (-1: gone).
template <class T>
std::vector<int> compact(std::vector<T>* v, const std::vector<char>& keep) {
  std::vector<int> remap(v->size(), -1);
  int next = 0;
  for (std::size_t i = 0; i < v->size(); ++i) {
    if (!keep[i]) continue;
    remap[i] = next;
    (*v)[next++] = (*v)[i];
  }
  v->resize(next);
  return remap;
}

void remap_list(std::vector<int>* list, const std::vector<int>& remap) {
  std::vector<int> out;
  for (const int i : *list) {
    if (i >= 0 && i < static_cast<int>(remap.size()) && remap[i] >= 0) out.push_back(remap[i]);
  }
  *list = std::move(out);
}

}  // namespace

bool MeshReport::clean() const {
  return duplicate_nodes == 0 && bad_index_elements == 0 && repeated_node_elements == 0 &&
         zero_volume_tetrahedra == 0 && zero_volume_hexahedra == 0 && inverted_tetrahedra == 0 &&
         inverted_hexahedra == 0 && distorted_hexahedra == 0 && degenerate_triangles == 0 &&
         unreferenced_nodes == 0;
}

std::string to_string(const MeshReport& r) {
  if (r.clean()) return "clean\n";
  std::string s;
  auto line = [&s](int n, const char* what) {
    if (n > 0) s += std::string(what) + ": " + std::to_string(n) + "\n";
  };
  line(r.duplicate_nodes, "duplicate nodes (merged)");
  line(r.bad_index_elements, "elements with out-of-range nodes (dropped)");
  line(r.repeated_node_elements, "elements repeating a node (dropped)");
  line(r.zero_volume_tetrahedra, "zero-volume tetrahedra (dropped)");
  line(r.zero_volume_hexahedra, "zero-volume hexahedra (dropped)");
  line(r.inverted_tetrahedra, "inverted tetrahedra (flipped)");
  line(r.inverted_hexahedra, "inverted hexahedra (flipped)");
  line(r.distorted_hexahedra, "distorted hexahedra (kept)");
  line(r.degenerate_triangles, "degenerate triangles (dropped)");
  line(r.unreferenced_nodes, "unreferenced nodes (dropped)");
  return s;
}

double hex_volume(const std::array<Vec3, 8>& x) {
  const double g[2] = {0.5 - 0.5 / std::sqrt(3.0), 0.5 + 0.5 / std::sqrt(3.0)};
  double v = 0;
  for (const double u : g) {
    for (const double s : g) {
      for (const double w : g) v += hex_jacobian(x, u, s, w);
    }
  }
  return v / 8.0;  // each Gauss weight is 1/2 per axis on [0, 1]
}

double total_volume(const Mesh& mesh) {
  const int n = static_cast<int>(mesh.nodes.size());
  const auto& x = mesh.nodes;
  double v = 0;
  for (const auto& t : mesh.tetrahedra) {
    if (indices_valid(t, n)) v += tet_volume(x[t[0]], x[t[1]], x[t[2]], x[t[3]]);
  }
  for (const auto& h : mesh.hexahedra) {
    if (indices_valid(h, n)) v += hex_volume(hex_points(x, h));
  }
  return v;
}

BoundingBox bounding_box(const Mesh& mesh) {
  BoundingBox box;
  bool any = false;
  for (const Vec3& p : mesh.nodes) {
    if (!p.allFinite()) continue;
    box.min = any ? box.min.cwiseMin(p) : p;
    box.max = any ? box.max.cwiseMax(p) : p;
    any = true;
  }
  return box;
}

MeshReport repair(Mesh& mesh, const RepairOptions& options) {
  MeshReport r;
  const int n = static_cast<int>(mesh.nodes.size());
  const std::vector<Vec3>& x = mesh.nodes;

  // 1. Duplicate nodes: every element is rewritten to use the representative.
  const BoundingBox box = bounding_box(mesh);
  const double tol = options.merge_tolerance * (box.max - box.min).norm();
  const std::vector<int> rep = duplicate_representatives(x, tol, box.min);
  for (int i = 0; i < n; ++i) r.duplicate_nodes += rep[i] != i;

  // 2. Elements: out-of-range or repeated nodes, then flat, then inverted.
  auto relink = [&](auto& e) {
    for (int& i : e) i = rep[i];
  };
  std::vector<char> keep_tet(mesh.tetrahedra.size(), 1);
  for (std::size_t k = 0; k < mesh.tetrahedra.size(); ++k) {
    auto& t = mesh.tetrahedra[k];
    if (!indices_valid(t, n)) {
      ++r.bad_index_elements;
      keep_tet[k] = 0;
      continue;
    }
    relink(t);
    if (repeats_node(t)) {
      ++r.repeated_node_elements;
      keep_tet[k] = 0;
      continue;
    }
    const double v = tet_volume(x[t[0]], x[t[1]], x[t[2]], x[t[3]]);
    const double scale = std::pow(longest_edge(x, t), 3);
    if (!(std::abs(v) > options.volume_tolerance * scale)) {  // NaN counts as flat
      ++r.zero_volume_tetrahedra;
      keep_tet[k] = 0;
    } else if (v < 0) {
      ++r.inverted_tetrahedra;
      std::swap(t[2], t[3]);
    }
  }
  std::vector<char> keep_hex(mesh.hexahedra.size(), 1);
  for (std::size_t k = 0; k < mesh.hexahedra.size(); ++k) {
    auto& h = mesh.hexahedra[k];
    if (!indices_valid(h, n)) {
      ++r.bad_index_elements;
      keep_hex[k] = 0;
      continue;
    }
    relink(h);
    if (repeats_node(h)) {
      ++r.repeated_node_elements;
      keep_hex[k] = 0;
      continue;
    }
    const double v = hex_volume(hex_points(x, h));
    const double scale = std::pow(longest_edge(x, h), 3);
    if (!(std::abs(v) > options.volume_tolerance * scale)) {
      ++r.zero_volume_hexahedra;
      keep_hex[k] = 0;
      continue;
    }
    if (v < 0) {
      ++r.inverted_hexahedra;
      h = {h[4], h[5], h[6], h[7], h[0], h[1], h[2], h[3]};  // mirror top <-> bottom
    }
    const std::array<Vec3, 8> p = hex_points(x, h);
    for (const auto& c : kCorner) {
      if (hex_jacobian(p, c[0], c[1], c[2]) <= 0) {
        ++r.distorted_hexahedra;
        break;
      }
    }
  }
  std::vector<char> keep_tri(mesh.triangles.size(), 1);
  for (std::size_t k = 0; k < mesh.triangles.size(); ++k) {
    auto& t = mesh.triangles[k];
    if (!indices_valid(t, n)) {
      ++r.degenerate_triangles;
      keep_tri[k] = 0;
      continue;
    }
    relink(t);
    if (repeats_node(t)) {
      ++r.degenerate_triangles;
      keep_tri[k] = 0;
    }
  }
  const std::vector<int> tet_remap = compact(&mesh.tetrahedra, keep_tet);
  const std::vector<int> hex_remap = compact(&mesh.hexahedra, keep_hex);
  compact(&mesh.triangles, keep_tri);
  for (Region& region : mesh.regions) {
    remap_list(&region.tetrahedra, tet_remap);
    remap_list(&region.hexahedra, hex_remap);
  }

  // 3. Nodes used by no element (merged duplicates included) go; indices are remapped.
  std::vector<char> used(n, 0);
  auto mark = [&](const auto& e) {
    for (const int i : e) used[i] = 1;
  };
  for (const auto& e : mesh.tetrahedra) mark(e);
  for (const auto& e : mesh.hexahedra) mark(e);
  for (const auto& e : mesh.triangles) mark(e);
  for (int i = 0; i < n; ++i) r.unreferenced_nodes += !used[i] && rep[i] == i;
  const std::vector<int> node_remap = compact(&mesh.nodes, used);
  auto renumber = [&](auto& e) {
    for (int& i : e) i = node_remap[i];
  };
  for (auto& e : mesh.tetrahedra) renumber(e);
  for (auto& e : mesh.hexahedra) renumber(e);
  for (auto& e : mesh.triangles) renumber(e);
  return r;
}

MeshReport inspect(const Mesh& mesh, const RepairOptions& options) {
  Mesh copy = mesh;
  return repair(copy, options);
}

std::vector<std::array<int, 2>> unique_edges(const Mesh& mesh) {
  std::vector<std::array<int, 2>> edges;
  edges.reserve(6 * mesh.tetrahedra.size());
  for (const auto& t : mesh.tetrahedra) {
    for (int i = 0; i < 4; ++i) {
      for (int j = i + 1; j < 4; ++j) {
        if (t[i] != t[j]) edges.push_back({std::min(t[i], t[j]), std::max(t[i], t[j])});
      }
    }
  }
  std::sort(edges.begin(), edges.end());
  edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
  return edges;
}

std::vector<std::array<int, 2>> spring_pairs(const Mesh& mesh) {
  std::vector<std::array<int, 2>> pairs = unique_edges(mesh);
  pairs.reserve(pairs.size() + 28 * mesh.hexahedra.size());
  for (const auto& h : mesh.hexahedra) {
    for (int i = 0; i < 8; ++i) {
      for (int j = i + 1; j < 8; ++j) {
        if (h[i] != h[j]) pairs.push_back({std::min(h[i], h[j]), std::max(h[i], h[j])});
      }
    }
  }
  std::sort(pairs.begin(), pairs.end());
  pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
  return pairs;
}

std::vector<std::array<int, 3>> surface_triangles(const Mesh& mesh) {
  // Outward faces of a positive tet (a, b, c, d): opposite a, b, c, d in turn.
  constexpr int kFace[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};
  struct Face {
    std::array<int, 3> key;  // sorted node indices
    int tet, local;
  };
  std::vector<Face> faces;
  faces.reserve(4 * mesh.tetrahedra.size());
  for (int t = 0; t < static_cast<int>(mesh.tetrahedra.size()); ++t) {
    const auto& e = mesh.tetrahedra[t];
    for (int f = 0; f < 4; ++f) {
      std::array<int, 3> key = {e[kFace[f][0]], e[kFace[f][1]], e[kFace[f][2]]};
      std::sort(key.begin(), key.end());
      faces.push_back({key, t, f});
    }
  }
  std::sort(faces.begin(), faces.end(), [](const Face& a, const Face& b) {
    return std::tie(a.key, a.tet, a.local) < std::tie(b.key, b.tet, b.local);
  });
  std::vector<Face> boundary;
  for (std::size_t i = 0; i < faces.size();) {
    std::size_t j = i + 1;
    while (j < faces.size() && faces[j].key == faces[i].key) ++j;
    if (j - i == 1) boundary.push_back(faces[i]);
    i = j;
  }
  std::sort(boundary.begin(), boundary.end(), [](const Face& a, const Face& b) {
    return std::tie(a.tet, a.local) < std::tie(b.tet, b.local);
  });
  std::vector<std::array<int, 3>> out;
  out.reserve(boundary.size());
  for (const Face& f : boundary) {
    const auto& e = mesh.tetrahedra[f.tet];
    out.push_back({e[kFace[f.local][0]], e[kFace[f.local][1]], e[kFace[f.local][2]]});
  }
  return out;
}

}  // namespace conica::io
