#!/usr/bin/env bash
# The liver by hand (docs/contact.md): serves the two livers with surface contact
# (configs/liver.pbtxt, and configs/liver-ef30.pbtxt, the calibrated liver served multi-rate; each
# from a copy whose probe block says `contact: SURFACE`, whatever the config says) and drives each, in real
# time at 1 kHz with conica-probe, with a sphere of the scene's radius (10 mm) and a 2 mm one:
#   approach from 1 mm off the rest surface, press 5 mm along the surface normal at 10 mm/s, hold
#   2 s, drag 20 mm along the surface at the held depth at 10 mm/s, lift off.
# The press point is the liver's top-most surface node (along +y, the scene's up), pressed along -y
# (the sphere's contact normal there); the drag goes along +x, the flattest way from it, with the
# centre kept 5 mm below the height at which the sphere touches the rest surface (computed from the
# mesh). Writes the trajectories, replies and server logs into OUT (default: a temp dir), draws
# docs/figures/liver-by-hand.png and prints the checks. About 30 s.
#   scripts/liver-by-hand.sh            # OUT_DIR=out/liver-by-hand to keep the files somewhere
set -euo pipefail
cd "$(dirname "$0")/.."
bin=${BUILD_DIR:-build}/bin
out=${OUT_DIR:-$(mktemp -d)}
mkdir -p "$out"
port=${CONICA_PORT_BASE:-5655}  # not the default 5555, so as not to meet another server
figure=${FIGURE:-docs/figures/liver-by-hand.png}
scenes=(configs/liver.pbtxt configs/liver-ef30.pbtxt)
radii=(0.01 0.002)
for b in conica-server conica-probe; do
  [ -x "$bin/$b" ] || { echo "$bin/$b missing: build first (scripts/setup.sh)" >&2; exit 2; }
done

copies=() server=
cleanup() {
  if [ -n "$server" ] && kill -0 "$server" 2>/dev/null; then kill -INT "$server"; wait "$server" || true; fi
  rm -f "${copies[@]}"
}
trap cleanup EXIT

# 1. Trajectories: t,probe,x,y,z every 1 ms, one per radius, and what each row means (phase, rest
#    surface height under the tool, depth below it, the rest surface normal) for the report.
/usr/bin/python3 - "${scenes[0]}" "$out" "${radii[@]}" <<'PY'
import json, os, re, sys
import numpy as np
scene, out, radii = sys.argv[1], sys.argv[2], [float(r) for r in sys.argv[3:]]
text = open(scene).read()
mesh = os.path.join(os.path.dirname(scene), re.search(r'path:\s*"([^"]+)"', text).group(1))
scale = float(re.search(r'scale:\s*([0-9.eE+-]+)', text).group(1))
lines = open(mesh).read().split("\n")  # Gmsh v1: $NOD, $ELM (type 4: tetrahedron)
i = lines.index("$NOD"); n = int(lines[i + 1]); ids = {}; P = []
for k in range(n):
    a = lines[i + 2 + k].split(); ids[int(a[0])] = k; P.append([float(x) for x in a[1:4]])
P = np.array(P) * scale
j = lines.index("$ELM"); faces = {}
for k in range(int(lines[j + 1])):
    a = lines[j + 2 + k].split()
    if a[1] != "4": continue
    t = [ids[int(x)] for x in a[5:9]]
    for f in ((0, 1, 2), (0, 1, 3), (0, 2, 3), (1, 2, 3)):
        key = tuple(sorted(t[q] for q in f))
        faces[key] = None if key in faces else t
tri = []  # boundary faces, outward
for key, tet in faces.items():
    if tet is None: continue
    a, b, c = P[list(key)]; nn = np.cross(b - a, c - a)
    opp = P[[v for v in tet if v not in key][0]]
    tri.append(key if np.dot(nn, opp - a) < 0 else (key[0], key[2], key[1]))
surf = sorted({v for t in tri for v in t})
top = surf[int(np.argmax(P[surf, 1]))]
x0, y0, z0 = P[top]
# The height at which a sphere lowered along -y over (x, z) touches the rest surface, and the
# contact normal there (vertices, edges and face interiors of the upward faces, exactly).
def make_touch(P, tri):
    tri = np.asarray(tri)
    A, B, C = P[tri[:, 0]], P[tri[:, 1]], P[tri[:, 2]]
    N = np.cross(B - A, C - A); N /= np.linalg.norm(N, axis=1)[:, None]
    up = N[:, 1] > 1e-9
    A, B, C, N = A[up], B[up], C[up], N[up]
    E = np.unique(np.sort(np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]]), 1), axis=0)
    E0, E1 = P[E[:, 0]], P[E[:, 1]]
    V = P[np.unique(tri)]
    def touch(x, z, R):
        best = (-np.inf, None)
        # vertices
        r2 = (V[:, 0] - x) ** 2 + (V[:, 2] - z) ** 2; m = r2 < R * R
        if m.any():
            h = V[m, 1] + np.sqrt(R * R - r2[m]); i = np.argmax(h); best = (h[i], V[m][i])
        # edges: f(t) = y(t) + sqrt(R^2 - r(t)^2) is concave where r(t) < R: golden section
        def f(t):
            p = E0 + t[:, None] * (E1 - E0)
            q = R * R - (p[:, 0] - x) ** 2 - (p[:, 2] - z) ** 2
            return np.where(q > 0, p[:, 1] + np.sqrt(np.maximum(q, 0)), -np.inf), p
        # feasible interval: |d + t e|^2 < R^2 in the xz plane
        dx, dz = E0[:, 0] - x, E0[:, 2] - z; ex, ez = E1[:, 0] - E0[:, 0], E1[:, 2] - E0[:, 2]
        qa = ex * ex + ez * ez; qb = 2 * (dx * ex + dz * ez); qc = dx * dx + dz * dz - R * R
        disc = qb * qb - 4 * qa * qc; ok = (disc > 0) & (qa > 0)
        sq = np.sqrt(np.maximum(disc, 0)); qa1 = np.where(qa > 0, qa, 1)
        lo = np.clip((-qb - sq) / (2 * qa1), 0, 1); hi = np.clip((-qb + sq) / (2 * qa1), 0, 1)
        ok &= hi > lo; g = (np.sqrt(5) - 1) / 2
        for _ in range(50):
            a = hi - g * (hi - lo); b = lo + g * (hi - lo)
            fa, _ = f(a); fb, _ = f(b)
            left = fa > fb
            hi = np.where(left, b, hi); lo = np.where(left, lo, a)
        fe, pe = f((lo + hi) / 2); fe = np.where(ok, fe, -np.inf)
        i = np.argmax(fe)
        if fe[i] > best[0]: best = (fe[i], pe[i])
        # face interiors: tangent point p = c - R n
        px = x - R * N[:, 0]; pz = z - R * N[:, 2]
        # barycentric in the xz projection
        v0 = C - A; v1 = B - A
        v2x = px - A[:, 0]; v2z = pz - A[:, 2]
        d00 = v0[:, 0] ** 2 + v0[:, 2] ** 2; d01 = v0[:, 0] * v1[:, 0] + v0[:, 2] * v1[:, 2]
        d11 = v1[:, 0] ** 2 + v1[:, 2] ** 2; d20 = v2x * v0[:, 0] + v2z * v0[:, 2]; d21 = v2x * v1[:, 0] + v2z * v1[:, 2]
        den = d00 * d11 - d01 * d01
        u = (d11 * d20 - d01 * d21) / den; v = (d00 * d21 - d01 * d20) / den
        ins = (u >= 0) & (v >= 0) & (u + v <= 1)
        if ins.any():
            py = A[:, 1] + u * v0[:, 1] + v * v1[:, 1]
            h = np.where(ins, py + R * N[:, 1], -np.inf); i = np.argmax(h)
            if h[i] > best[0]: best = (h[i], np.array([px[i], py[i], pz[i]]))
        h, p = best
        c = np.array([x, h, z]); return h, (c - p) / np.linalg.norm(c - p)
    return touch
touch = make_touch(P, tri)
v, approach, depth, hold, drag, lift_to, rest = 0.010, 0.001, 0.005, 2.0, 0.020, 0.002, 0.3
meta = {"node": int(top), "point": [x0, y0, z0], "radii": radii, "runs": []}
for R in radii:
    grid = np.arange(0, drag + 1e-9, 1e-4)
    hn = [touch(x0 + s, z0, R) for s in grid]
    hs = np.array([h for h, _ in hn]); ns = np.array([nv for _, nv in hn])
    t_press = (approach + depth) / v; t_hold = t_press + hold; t_drag = t_hold + drag / v
    t_lift = t_drag + (depth + lift_to) / v; t_end = t_lift + rest
    rows = []
    for k in range(int(round(t_end * 1000)) + 1):
        t = k * 1e-3; s = 0.0
        if t <= t_press: d, ph = -approach + v * t, ("approach" if t < approach / v else "press")
        elif t <= t_hold: d, ph = depth, "hold"
        elif t <= t_drag: d, s, ph = depth, v * (t - t_hold), "drag"
        elif t <= t_lift: d, s, ph = depth - v * (t - t_drag), drag, "lift"
        else: d, s, ph = -lift_to, drag, "off"
        h = np.interp(s, grid, hs); nrm = [np.interp(s, grid, ns[:, c]) for c in range(3)]
        rows.append((t, ph, s, h, d, x0 + s, h - d, z0, nrm))
    name = f"R{R * 1000:g}mm"
    with open(os.path.join(out, f"traj-{name}.csv"), "w") as f:
        f.write("t,probe,x,y,z\n")
        for r in rows: f.write(f"{r[0]:.3f},0,{r[5]:.9f},{r[6]:.9f},{r[7]:.9f}\n")
    with open(os.path.join(out, f"plan-{name}.csv"), "w") as f:
        f.write("t,phase,s,h,depth,nx,ny,nz\n")
        for r in rows: f.write(f"{r[0]:.3f},{r[1]},{r[2]:.9f},{r[3]:.9f},{r[4]:.9f},{r[8][0]:.6f},{r[8][1]:.6f},{r[8][2]:.6f}\n")
    meta["runs"].append({"name": name, "R": R, "drop_mm": 1e3 * (hs[0] - hs[-1]),
                         "tilt_deg_max": float(np.degrees(np.arccos(ns[:, 1].min()))),
                         "phases": {"press": [approach / v, t_press], "hold": [t_press, t_hold],
                                    "drag": [t_hold, t_drag], "lift": [t_drag, t_lift]}})
json.dump(meta, open(os.path.join(out, "plan.json"), "w"), indent=1)
print(f"press point: top-most surface node {top} at ({x0:.5f}, {y0:.5f}, {z0:.5f}) m, along -y; "
      f"drag along +x: the rest surface under the tool falls "
      + ", ".join(f"{r['drop_mm']:.2f} mm ({r['name']})" for r in meta["runs"]) + " over 20 mm")
PY

# 2. Serve each liver with a fresh server per sphere (one server at a time: the soft liver takes
#    seconds to come back after a lift, so a second press on the same server would start into a
#    dent) and drive it.
for scene in "${scenes[@]}"; do
  base=$(basename "$scene" .pbtxt)
  copy="$(dirname "$scene")/.by-hand-$$-$base.pbtxt"  # next to it, for the mesh path
  copies+=("$copy")
  sed -E -e '/^probe \{/s/ contact: [A-Z_]+//' -e 's/^(probe \{[^}]*)\}/\1contact: SURFACE }/' "$scene" >"$copy"
  grep -q '^probe {.*contact: SURFACE' "$copy" || { echo "$scene: no one-line probe block to switch" >&2; exit 2; }
  for R in "${radii[@]}"; do
    name=R$(awk -v r="$R" 'BEGIN { printf "%gmm", r * 1000 }')
    log="$out/server-$base-$name.log"
    "$bin/conica-server" --scene "$copy" --seconds 30 --stats-seconds 1 \
      --probe-endpoint "tcp://127.0.0.1:$port" --state-endpoint "tcp://127.0.0.1:$((port + 1))" \
      --control-endpoint "tcp://127.0.0.1:$((port + 2))" >"$log" 2>&1 &
    server=$!
    for _ in $(seq 150); do
      grep -q "serving:" "$log" && break
      kill -0 "$server" 2>/dev/null || { cat "$log" >&2; exit 1; }
      sleep 0.2
    done
    grep -q "serving:" "$log" || { echo "$scene: the server did not come up" >&2; cat "$log" >&2; exit 1; }
    sleep 0.5
    "$bin/conica-probe" --endpoint "tcp://127.0.0.1:$port" --trajectory "$out/traj-$name.csv" \
      --radius "$R" --rate-hz 1000 --realtime -o "$out/replies-$base-$name.csv" \
      2>"$out/probe-$base-$name.log" || { cat "$out/probe-$base-$name.log" >&2; exit 1; }
    kill -INT "$server"
    wait "$server" || true
    server=
    echo "$base $name: $(tail -1 "$out/probe-$base-$name.log" | sed 's/^conica-probe: //');" \
      "server $(grep -oE "stopped after .*" "$log")"
  done
done

# 3. Checks and the figure.
MPLBACKEND=Agg /usr/bin/python3 - "$out" "$figure" "${scenes[@]}" <<'PY'
import csv, json, math, os, re, sys
import numpy as np
out, figure, scenes = sys.argv[1], sys.argv[2], sys.argv[3:]
meta = json.load(open(os.path.join(out, "plan.json")))
def load(path):
    rows = list(csv.DictReader(open(path)))
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0]} if rows else None
def ripple(x):  # minus its centred 21-tick moving average: rms, largest, main frequency
    r = (x - np.convolve(x, np.ones(21) / 21, "same"))[10:-10]
    sp = np.abs(np.fft.rfft(r * np.hanning(len(r))))
    return r.std(), np.abs(r).max(), np.fft.rfftfreq(len(r), 1e-3)[1 + np.argmax(sp[1:])]
results = []
for scene in scenes:
    base = os.path.basename(scene)[:-len(".pbtxt")]
    for run in meta["runs"]:
        name = run["name"]
        log = open(os.path.join(out, f"server-{base}-{name}.log")).read()
        st = re.findall(r"stopped after (\d+) ticks \((\d+) missed\), (\d+) probes, (\d+) errors", log)
        ticks, missed, _, errors = map(int, st[-1]) if st else (0, -1, 0, -1)
        steps = re.findall(r"step p50/p99 (\d+)/(\d+) us", log)
        step_p99 = max(int(b) for _, b in steps) if steps else float("nan")
        late = max([int(x) for x in re.findall(r"lateness p50/p99/max \d+/\d+/(\d+) us", log)] or [0])
        rollbacks = max([int(x) for x in re.findall(r"rollbacks (\d+)", log)] or [0])
        plan = list(csv.DictReader(open(os.path.join(out, f"plan-{name}.csv"))))
        rep = load(os.path.join(out, f"replies-{base}-{name}.csv"))
        idx = np.rint(rep["t"] * 1000).astype(int)  # the plan row of each reply
        ph = np.array([plan[i]["phase"] for i in idx])
        d = np.array([float(plan[i]["depth"]) for i in idx]) * 1e3  # mm below the rest surface
        s = np.array([float(plan[i]["s"]) for i in idx]) * 1e3
        n = np.array([[float(plan[i][c]) for c in ("nx", "ny", "nz")] for i in idx])
        F = np.stack([rep["fx"], rep["fy"], rep["fz"]], 1)
        nan = int(np.sum(~np.isfinite(F)))
        F = np.nan_to_num(F)
        Fm = np.linalg.norm(F, axis=1); Fn = np.sum(F * n, 1)
        Ft = np.linalg.norm(F - Fn[:, None] * n, axis=1)
        lost = len(plan) - len(rep["t"])
        inside = np.isin(ph, ["press", "hold", "drag"]) & (d >= 0.1)
        first = d[np.isin(ph, ["approach", "press"]) & (Fm > 0)]
        pr = (ph == "press") & (d >= 0)
        runmax = np.maximum.accumulate(Fn[pr]); drop = runmax - Fn[pr]
        k = int(np.argmax(drop / np.maximum(runmax, 1e-12)))
        prr = (ph == "press") & (d >= 0.5)
        pr_rms, pr_max, pr_hz = ripple(Fn[prr])
        h0, h1 = run["phases"]["hold"]
        hl = (rep["t"] >= h1 - 1.0) & (rep["t"] < h1)
        stop = (rep["t"] >= h0) & (rep["t"] < h0 + 0.1)
        dr = (ph == "drag") & (s >= 5) & (s <= 15)
        tdir = np.array([1.0, 0, 0])[None, :] - n[:, 0:1] * n  # the drag direction in the tangent plane
        tdir /= np.linalg.norm(tdir, axis=1)[:, None]
        Fdrag = np.sum(F * tdir, 1)  # along the drag: negative resists it
        dr_rms, dr_max, dr_hz = ripple(Fn[dr])
        lift = ph == "lift"
        zl = np.where(lift & (Fm <= 0))[0]
        later = np.isin(ph, ["lift", "off"]) & (np.arange(len(ph)) > (zl[0] if zl.size else len(ph)))
        lf = np.where(lift & (Fm > 0))[0]
        li_rms, li_max, li_hz = ripple(Fn[lf]) if len(lf) > 40 else (0.0, 0.0, 0.0)
        toggles = int(np.sum(np.abs(np.diff(rep["contact"][later])))) if later.any() else 0
        rise = np.diff(Fm); q = int(np.argmax(rise))  # the largest kick from one reply to the next
        med = np.array([np.median(Fm[max(0, i - 10):i + 11]) for i in range(len(Fm))])
        spike = np.where(med > 0.05 * Fm.max(), Fm / np.maximum(med, 1e-300), 0); w = int(np.argmax(spike))
        results.append(dict(
            scene=base, run=name, R=run["R"], sent=len(plan), replies=len(rep["t"]), lost=lost, nan=nan,
            first_force_mm=float(first.min()) if first.size else float("nan"),
            zero_inside=int(np.sum(inside & ((Fm <= 0) | (rep["contact"] == 0)))),
            nonpos_normal_inside=int(np.sum(inside & (Fn <= 0))),
            F_at_5mm=float(Fn[pr][-1]), drops_1pct=int(np.sum(drop > 0.01 * runmax)),
            max_drop=float(drop[k]), max_drop_pct=float(100 * drop[k] / max(runmax[k], 1e-12)),
            max_drop_at_mm=float(d[pr][k]), press_ripple_rms=float(pr_rms), press_ripple_max=float(pr_max),
            press_ripple_hz=float(pr_hz), stop_min=float(Fm[stop].min()), stop_max=float(Fm[stop].max()),
            hold_mean=float(Fm[hl].mean()), hold_std_pct=float(100 * Fm[hl].std() / max(Fm[hl].mean(), 1e-300)),
            drag_Fn_mean=float(Fn[dr].mean()), drag_Fn_min=float(Fn[dr].min()), drag_Fn_max=float(Fn[dr].max()),
            drag_ripple_pct=float(100 * (Fn[dr].max() - Fn[dr].min()) / Fn[dr].mean()),
            drag_ripple_rms=float(dr_rms), drag_ripple_hz=float(dr_hz),
            drag_Ft_mean=float(Ft[dr].mean()), drag_Ft_max=float(Ft[dr].max()), drag_Fdrag_mean=float(Fdrag[dr].mean()),
            drag_Fdrag_min=float(Fdrag[ph == "drag"].min()), drag_Fdrag_max=float(Fdrag[ph == "drag"].max()),
            lift_ripple_rms=float(li_rms), lift_ripple_max=float(li_max), lift_ripple_hz=float(li_hz),
            release_toggles=toggles, kick=float(rise[q]), kick_from=float(Fm[q]), kick_phase=str(ph[q + 1]),
            kick_depth=float(d[q + 1]), spike=float(spike[w]), spike_phase=str(ph[w]), spike_depth=float(d[w]),
            release_depth_mm=float(d[zl[0]]) if zl.size else float("nan"),
            after_release_max=float(Fm[later].max()) if later.any() else 0.0, max_F=float(Fm.max()),
            rtt_p99_us=float(np.percentile(rep["rtt_us"], 99)), rtt_max_us=float(rep["rtt_us"].max()),
            ticks=ticks, missed=missed, errors=errors, step_p99_us=step_p99, lateness_max_us=late, rollbacks=rollbacks,
            t=rep["t"], Fm=Fm, Fn=Fn, Ft=Ft, d=d, ph=ph, phases=run["phases"]))
json.dump([{k: v for k, v in r.items() if not isinstance(v, (np.ndarray, dict))} for r in results],
          open(os.path.join(out, "checks.json"), "w"), indent=1)

def N(x): return f"{1e3 * x:.1f} mN" if abs(x) < 1 else f"{x:.2f} N"
rows = [("scene, sphere", lambda r: f"{r['scene']}, {1e3 * r['R']:g} mm"),
        ("first force at (depth)", lambda r: f"{r['first_force_mm']:.2f} mm"),
        ("replies >= 0.1 mm inside with F = 0 / Fn <= 0", lambda r: f"{r['zero_inside']} / {r['nonpos_normal_inside']}"),
        ("normal force at 5 mm", lambda r: N(r["F_at_5mm"])),
        ("press: replies > 1 % below the running max", lambda r: f"{r['drops_1pct']}"),
        ("press: largest drop", lambda r: f"{N(r['max_drop'])} ({r['max_drop_pct']:.1f} %) at {r['max_drop_at_mm']:.2f} mm"),
        ("press ripple rms (max), main freq.", lambda r: f"{N(r['press_ripple_rms'])} ({N(r['press_ripple_max'])}), {r['press_ripple_hz']:.0f} Hz"),
        ("press stops: first 0.1 s of hold", lambda r: f"{N(r['stop_min'])} - {N(r['stop_max'])}"),
        ("hold, last 1 s: mean, std / mean", lambda r: f"{N(r['hold_mean'])}, {r['hold_std_pct']:.3f} %"),
        ("drag 5-15 mm: normal force min - max", lambda r: f"{N(r['drag_Fn_min'])} - {N(r['drag_Fn_max'])}"),
        ("drag: (max - min) / mean normal", lambda r: f"{r['drag_ripple_pct']:.0f} %"),
        ("drag: tangential mean, / normal mean", lambda r: f"{N(r['drag_Ft_mean'])}, {100 * r['drag_Ft_mean'] / r['drag_Fn_mean']:.0f} %"),
        ("drag: along the drag, whole drag min - max (< 0 resists)", lambda r: f"{N(r['drag_Fdrag_min'])} - {N(r['drag_Fdrag_max'])}"),
        ("lift ripple rms (max), main freq.", lambda r: f"{N(r['lift_ripple_rms'])} ({N(r['lift_ripple_max'])}), {r['lift_ripple_hz']:.0f} Hz"),
        ("lift: force first 0 at (depth)", lambda r: f"{r['release_depth_mm']:.2f} mm"),
        ("after that: contact toggles, largest force", lambda r: f"{r['release_toggles']}, {N(r['after_release_max'])}"),
        ("largest rise from one reply to the next", lambda r: f"{N(r['kick_from'])} -> {N(r['kick_from'] + r['kick'])} ({r['kick_phase']}, {r['kick_depth']:.2f} mm)"),
        ("largest force / median of its 21 replies", lambda r: f"{r['spike']:.2f} ({r['spike_phase']}, {r['spike_depth']:.2f} mm)"),
        ("NaN / lost replies / errors", lambda r: f"{r['nan']} / {r['lost']} of {r['sent']} / {r['errors']}"),
        ("missed ticks (server run) / rollbacks", lambda r: f"{r['missed']} of {r['ticks']} / {r['rollbacks']}"),
        ("tick step p99 (worst second) / lateness max", lambda r: f"{r['step_p99_us']:.0f} us / {r['lateness_max_us']} us"),
        ("round trip p99 / max", lambda r: f"{r['rtt_p99_us']:.0f} us / {r['rtt_max_us']:.0f} us")]
print("\nchecks (depth: of the sphere below where it touches the rest surface; normal: the rest "
      "surface's contact normal under the tool; drag over its middle, 5-15 mm of 20 mm)")
print("| check | " + " | ".join(f(r) for r in results for f in [rows[0][1]]) + " |")
print("|---|" + "---|" * len(results))
for label, f in rows[1:]:
    print(f"| {label} | " + " | ".join(f(r) for r in results) + " |")
print()
for r in results:
    flags = []
    if r["zero_inside"]: flags.append(f"POP-THROUGH: {r['zero_inside']} replies with no force while >= 0.1 mm below the rest surface")
    if r["nonpos_normal_inside"] > r["zero_inside"]: flags.append("normal force <= 0 while inside")
    if not r["first_force_mm"] <= 0.1: flags.append(f"no force in the first 0.1 mm (first at {r['first_force_mm']:.2f} mm)")
    if r["nan"]: flags.append(f"{r['nan']} NaN force components")
    if r["lost"]: flags.append(f"{r['lost']} lost replies")
    if r["missed"]: flags.append(f"{r['missed']} missed ticks")
    if r["rollbacks"]: flags.append(f"{r['rollbacks']} rollbacks")
    if r["after_release_max"] > 0.01 * r["hold_mean"]: flags.append(f"touches again after the release ({N(r['after_release_max'])})")
    if r["spike"] > 1.5: flags.append(f"a spike of {r['spike']:.1f} x the local median force ({r['spike_phase']}, {r['spike_depth']:.2f} mm)")
    print(f"{r['scene']} {r['run']}: " + ("; ".join(flags) if flags else "felt within 0.1 mm, no pop-through, NaN, lost reply or missed tick"))

import matplotlib.pyplot as plt
fig, ax = plt.subplots(len(scenes), 3, figsize=(16, 4.2 * len(scenes)), squeeze=False)
colors = {"press": "#dbe9f6", "hold": "#e6f4e1", "drag": "#fbe5d6", "lift": "#eeeeee"}
for i, scene in enumerate(scenes):
    base = os.path.basename(scene)[:-len(".pbtxt")]
    rs = [r for r in results if r["scene"] == base]
    sc, unit = (1e3, "mN") if max(r["max_F"] for r in rs) < 1 else (1.0, "N")
    for j, r in enumerate(rs):
        a = ax[i][j]
        for p, (t0, t1) in r["phases"].items():
            a.axvspan(t0, t1, color=colors[p], lw=0)
            a.text((t0 + t1) / 2, 1.0, p, transform=a.get_xaxis_transform(), ha="center", va="bottom", fontsize=8)
        a.plot(r["t"], sc * r["Fm"], "k-", lw=1.0, label="|F|")
        a.plot(r["t"], sc * r["Fn"], "C0--", lw=1.0, label="normal component")
        a.plot(r["t"], sc * r["Ft"], "C3-", lw=0.7, label="tangential")
        a.set_xlabel("time (s)"); a.set_ylabel(f"force ({unit})")
        a.set_title(f"{base}, {1e3 * r['R']:g} mm sphere", pad=14, fontsize=10)
        a.legend(fontsize=8, loc="upper right"); a.grid(alpha=0.3)
        b = ax[i][2]
        for phs, style in ((("approach", "press"), "-"), (("lift",), ":")):
            m = np.isin(r["ph"], phs)
            b.plot(r["d"][m], sc * r["Fn"][m], style, color=f"C{j}", lw=1.0,
                   label=f"{1e3 * r['R']:g} mm, " + ("press" if "press" in phs else "lift"))
    b = ax[i][2]
    b.set_xlabel("depth below the rest surface (mm)"); b.set_ylabel(f"normal force ({unit})")
    b.set_title(f"{base}: normal force against depth", pad=14, fontsize=10)
    b.legend(fontsize=8); b.grid(alpha=0.3)
fig.suptitle("The liver by hand: press 5 mm at 10 mm/s, hold 2 s, drag 20 mm at 10 mm/s, lift "
             "(conica-server, surface contact; conica-probe --realtime, 1 kHz)", fontsize=11)
fig.tight_layout()
os.makedirs(os.path.dirname(figure) or ".", exist_ok=True)
fig.savefig(figure, dpi=110)
print(f"\nfigure: {figure}\nfiles: {out}")
PY
