#!/usr/bin/python3
"""Writes the meshes of tests/io/meshio_test.cc with meshio (Debian's python3-meshio), an
independent writer of Gmsh and VTK files, and what meshio put into them.

    /usr/bin/python3 tests/io/write_meshio_meshes.py [--small] OUT_DIR

Two meshes: `tet`, a perturbed 3 x 2 x 2 block of 12 unit cubes cut into 5 tetrahedra each,
and `hex`, a perturbed 3 x 3 x 2 block of hexahedra. Coordinates are random doubles with all 53
bits in use, so a reader that loses a bit is caught. Each mesh is written as

    NAME.gmsh22.msh / NAME.gmsh22-ascii.msh   Gmsh 2.2 binary / ASCII (physical and elementary
                                              tags per element)
    NAME.gmsh41.msh / NAME.gmsh41-ascii.msh   Gmsh 4.1 binary / ASCII (one volume entity,
                                              physical group 5, in $Entities)
    NAME.vtk51.vtk / NAME.vtk51-ascii.vtk     legacy VTK 5.1 BINARY / ASCII (OFFSETS layout)
    NAME.vtk42.vtk / NAME.vtk42-ascii.vtk     legacy VTK 4.2 BINARY / ASCII (counted cells)
    NAME.vtk42-float.vtk                      VTK 4.2 BINARY with float (32-bit) points
    NAME.vtu                                  VTK XML, which conica refuses

and NAME.expected: the points meshio was given, one "x y z" line each in Python's round-trip
repr (float32 points for the float file in NAME.expected-float), then "cells TYPE COUNT" and
one line of 0-based point indices per cell, then "physical" and the Gmsh 2.2 physical tag of
each cell on one line, then "physical41" and the 4.1 ones.
"""
import argparse
import os

import meshio
import numpy as np


def block(nx, ny, nz, rng):
    """Points of an (nx+1) x (ny+1) x (nz+1) grid, each moved by up to 0.2 at random, and the
    point index of grid corner (i, j, k)."""
    index = {}
    points = []
    for k in range(nz + 1):
        for j in range(ny + 1):
            for i in range(nx + 1):
                index[(i, j, k)] = len(points)
                points.append([i, j, k])
    points = np.array(points, dtype=np.float64)
    points += rng.uniform(-0.2, 0.2, size=points.shape)
    points *= 0.01  # a 3 cm block, in metres: no coordinate is a short decimal
    return points, index


def hexahedra(nx, ny, nz, index):
    cells = []
    for k in range(nz):
        for j in range(ny):
            for i in range(nx):
                c = [index[(i + a, j + b, k + e)] for (a, b, e) in
                     ((0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0),
                      (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1))]
                cells.append(c)
    return np.array(cells, dtype=np.int64)


def tetrahedra(hexes):
    """Five positive tetrahedra per hexahedron (the cube's corner 0..7 numbering)."""
    five = ((0, 1, 3, 4), (1, 2, 3, 6), (1, 4, 5, 6), (3, 6, 7, 4), (1, 3, 4, 6))
    return np.array([[h[i] for i in t] for h in hexes for t in five], dtype=np.int64)


def write_all(out, name, points, cell_type, cells):
    n = len(cells)
    physical = np.where(np.arange(n) < n // 2, 3, 7).astype(np.int32)
    geometrical = np.ones(n, dtype=np.int32)
    gmsh_mesh = meshio.Mesh(points, [(cell_type, cells)],
                            cell_data={"gmsh:physical": [physical],
                                       "gmsh:geometrical": [geometrical]})
    # Gmsh 4.1 keeps physical groups on entities: every node and cell on volume 1, physical 5.
    gmsh41_mesh = meshio.Mesh(points, [(cell_type, cells)],
                              point_data={"gmsh:dim_tags": np.tile([3, 1], (len(points), 1))},
                              cell_data={"gmsh:physical": [np.full(n, 5, dtype=np.int32)],
                                         "gmsh:geometrical": [geometrical]})
    plain = meshio.Mesh(points, [(cell_type, cells)])
    base = os.path.join(out, name)
    meshio.write(base + ".gmsh22.msh", gmsh_mesh, file_format="gmsh22", binary=True)
    meshio.write(base + ".gmsh22-ascii.msh", gmsh_mesh, file_format="gmsh22", binary=False)
    meshio.write(base + ".gmsh41.msh", gmsh41_mesh, file_format="gmsh", binary=True)
    meshio.write(base + ".gmsh41-ascii.msh", gmsh41_mesh, file_format="gmsh", binary=False)
    meshio.vtk.write(base + ".vtk51.vtk", plain, "5.1", binary=True)
    meshio.vtk.write(base + ".vtk51-ascii.vtk", plain, "5.1", binary=False)
    meshio.vtk.write(base + ".vtk42.vtk", plain, "4.2", binary=True)
    meshio.vtk.write(base + ".vtk42-ascii.vtk", plain, "4.2", binary=False)
    as_float = meshio.Mesh(points.astype(np.float32), [(cell_type, cells)])
    meshio.vtk.write(base + ".vtk42-float.vtk", as_float, "4.2", binary=True)
    meshio.write(base + ".vtu", plain)

    def expected(path, pts):
        with open(path, "w") as f:
            for p in pts:
                f.write(" ".join(repr(float(v)) for v in p) + "\n")
            f.write(f"cells {cell_type} {n}\n")
            for c in cells:
                f.write(" ".join(str(int(i)) for i in c) + "\n")
            f.write("physical\n")
            f.write(" ".join(str(int(t)) for t in physical) + "\n")
            f.write("physical41\n")
            f.write(" ".join("5" for t in physical) + "\n")

    expected(base + ".expected", points)
    expected(base + ".expected-float", points.astype(np.float32))


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("out", help="folder to write into")
    ap.add_argument("--small", action="store_true",
                    help="one cube per mesh (the fuzz seeds of fuzz/corpus/mesh)")
    args = ap.parse_args()
    os.makedirs(args.out, exist_ok=True)
    rng = np.random.default_rng(20260712)
    tet = (1, 1, 1) if args.small else (3, 2, 2)
    hexes = (1, 1, 1) if args.small else (3, 3, 2)
    pts, index = block(*tet, rng)
    write_all(args.out, "tet", pts, "tetra", tetrahedra(hexahedra(*tet, index)))
    pts, index = block(*hexes, rng)
    write_all(args.out, "hex", pts, "hexahedron", hexahedra(*hexes, index))


if __name__ == "__main__":
    main()
