#!/usr/bin/python3
"""The finer liver of configs/liver-fine-ef30.pbtxt: the boundary of SOFA's liver2.msh (the
triangles that belong to exactly one of its tetrahedra: 432 nodes, 860 triangles) tetrahedralised
by TetGen with a quality bound and a volume bound, written as Gmsh 2.2 ASCII.

  /usr/bin/python3 scripts/mesh-liver-fine.py [--volume A] [--quality Q] SRC.msh OUT.msh

The volume bound A is in the file's units (liver2.msh: about 0.1 m per unit); the scene scales by
0.1. TetGen runs as `tetgen -pq<Q>a<A>Q` on a .smesh of the boundary in a temporary folder.
"""
import argparse
import collections
import os
import subprocess
import sys
import tempfile


def read_gmsh1(path):
    """Nodes {id: (x, y, z)} and tetrahedra [(id, id, id, id)] of a Gmsh legacy v1 file."""
    with open(path) as f:
        lines = [l.strip() for l in f]
    i = lines.index("$NOD")
    n = int(lines[i + 1])
    nodes = {}
    for l in lines[i + 2:i + 2 + n]:
        t = l.split()
        nodes[int(t[0])] = tuple(float(v) for v in t[1:4])
    j = lines.index("$ELM")
    m = int(lines[j + 1])
    tets = []
    for l in lines[j + 2:j + 2 + m]:
        t = l.split()
        if int(t[1]) == 4:  # elm-number elm-type reg-phys reg-elem number-of-nodes nodes
            tets.append(tuple(int(v) for v in t[5:9]))
    return nodes, tets


def boundary(tets):
    """Faces that belong to one tetrahedron only, oriented outward (as the tetrahedron sees them,
    for a positively oriented tetrahedron; TetGen does not need a consistent orientation)."""
    count = collections.Counter()
    face_of = {}
    for a, b, c, d in tets:
        for f in ((a, b, c), (a, b, d), (a, c, d), (b, c, d)):
            k = tuple(sorted(f))
            count[k] += 1
            face_of[k] = f
    return [face_of[k] for k, c in count.items() if c == 1]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--volume", type=float, default=7e-4, help="largest tetrahedron volume (file units^3)")
    ap.add_argument("--quality", type=float, default=1.4, help="radius-edge ratio bound")
    ap.add_argument("src")
    ap.add_argument("out")
    a = ap.parse_args()
    nodes, tets = read_gmsh1(a.src)
    faces = boundary(tets)
    used = sorted({v for f in faces for v in f})
    index = {v: k for k, v in enumerate(used)}
    with tempfile.TemporaryDirectory() as tmp:
        smesh = os.path.join(tmp, "liver.smesh")
        with open(smesh, "w") as f:
            f.write(f"{len(used)} 3 0 0\n")
            for v in used:
                f.write(f"{index[v]} {nodes[v][0]!r} {nodes[v][1]!r} {nodes[v][2]!r}\n")
            f.write(f"{len(faces)} 0\n")
            for t in faces:
                f.write("3 " + " ".join(str(index[v]) for v in t) + "\n")
            f.write("0\n0\n")
        cmd = ["tetgen", f"-pq{a.quality}a{a.volume}Q", smesh]
        subprocess.run(cmd, check=True)
        base = os.path.join(tmp, "liver.1")
        with open(base + ".node") as f:
            rows = [l.split() for l in f if l.strip() and not l.startswith("#")]
        nn = int(rows[0][0])
        pts = [(int(r[0]), r[1], r[2], r[3]) for r in rows[1:1 + nn]]
        with open(base + ".ele") as f:
            rows = [l.split() for l in f if l.strip() and not l.startswith("#")]
        ne = int(rows[0][0])
        eles = [tuple(int(v) for v in r[1:5]) for r in rows[1:1 + ne]]
    first = min(p[0] for p in pts)  # TetGen numbers from 0 or 1, as its input did
    os.makedirs(os.path.dirname(os.path.abspath(a.out)), exist_ok=True)
    tmp_out = a.out + ".part"
    with open(tmp_out, "w") as f:
        f.write("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n%d\n" % nn)
        for p in pts:
            f.write(f"{p[0] - first + 1} {p[1]} {p[2]} {p[3]}\n")
        f.write("$EndNodes\n$Elements\n%d\n" % ne)
        for k, e in enumerate(eles):
            f.write(f"{k + 1} 4 2 1 1 " + " ".join(str(v - first + 1) for v in e) + "\n")
        f.write("$EndElements\n")
    os.replace(tmp_out, a.out)
    print(f"{a.out}: {nn} nodes, {ne} tetrahedra from {len(used)} boundary nodes and "
          f"{len(faces)} triangles ({' '.join(cmd[:2])})")


if __name__ == "__main__":
    sys.exit(main())
