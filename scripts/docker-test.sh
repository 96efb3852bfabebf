#!/usr/bin/env bash
# End-to-end test of docker/Dockerfile with podman, without any container registry:
#   1. installs podman, buildah, debootstrap and runc (apt-get) when missing;
#   2. creates the base image debian:bookworm locally when missing (debootstrap from the Debian
#      mirror named in this machine's apt sources, cached outside the repository);
#   3. builds the image conica:latest;
#   4. starts conica-server in a container, its ports published on 127.0.0.1 only;
#   5. probes it from the host (build/bin/conica-latency and conica-probe, or the image's own
#      clients on the host network when build/bin has none) and from a second container, and
#      checks the replies: few lost round trips, a force > 0 when pressing into the cube;
#   6. stops and removes the container.
# Exits non-zero, saying why, when anything is missing or fails. Bounded in time.
#   scripts/docker-test.sh
#   CONICA_PORT_BASE=25555 scripts/docker-test.sh        # host ports BASE..BASE+2 (default 15555)
#   CONICA_DEBIAN_MIRROR=http://host/debian scripts/docker-test.sh   # override the mirror
#   CONICA_DOCKER_CACHE=DIR                               # base rootfs cache (default ~/.cache/conica/docker)
#   CONICA_DOCKER_COMPOSE=1 scripts/docker-test.sh       # also run docker/compose.yaml (podman-compose)
set -euo pipefail
cd "$(dirname "$0")/.."

if [[ $(id -u) -ne 0 ]]; then
  command -v sudo >/dev/null || { echo "docker-test: needs root (or sudo) for apt-get, debootstrap and podman" >&2; exit 1; }
  exec sudo -E "$0" "$@"
fi

IMAGE=${CONICA_IMAGE:-localhost/conica:latest}
BASE=docker.io/library/debian:bookworm
PORT_BASE=${CONICA_PORT_BASE:-15555}
P_PROBE=$PORT_BASE P_STATE=$((PORT_BASE + 1)) P_CONTROL=$((PORT_BASE + 2))
CACHE=${CONICA_DOCKER_CACHE:-${XDG_CACHE_HOME:-$HOME/.cache}/conica/docker}
NAME=conica-test-$$
WORK=$(mktemp -d /tmp/conica-docker-test.XXXXXX)
mkdir -p "$CACHE"
t_start=$(date +%s)

say() { echo "docker-test: $*"; }
die() { echo "docker-test: FAIL: $*" >&2; exit 1; }

cleanup() {
  local rc=$?
  if podman container exists "$NAME" 2>/dev/null; then
    podman logs "$NAME" >"$WORK/server.log" 2>&1 || true
    timeout 30 podman rm -f -t 5 "$NAME" >/dev/null 2>&1 || true
  fi
  if ((rc != 0)) && [[ -s $WORK/server.log ]]; then
    echo "---- server log (last 20 lines) ----" >&2
    tail -n 20 "$WORK/server.log" >&2
  fi
  rm -rf "$WORK"
  exit $rc
}
trap cleanup EXIT

# ---- 1. tools ------------------------------------------------------------------------------
need=()
for c in podman:podman buildah:buildah debootstrap:debootstrap runc:runc; do
  command -v "${c%%:*}" >/dev/null || need+=("${c#*:}")
done
if ((${#need[@]})); then
  say "installing ${need[*]}"
  apt-get -o DPkg::Lock::Timeout=600 update -qq
  DEBIAN_FRONTEND=noninteractive apt-get -o DPkg::Lock::Timeout=600 install -y -qq "${need[@]}" >/dev/null
fi
for c in podman buildah debootstrap runc; do
  command -v "$c" >/dev/null || die "$c is not installed and apt-get could not install it"
done

# This machine's cgroup layout and limits need the runc runtime and modest ulimits.
cat >"$CACHE/containers.conf" <<'EOF'
[containers]
default_ulimits = ["nofile=20000:20000", "nproc=32768:32768"]

[engine]
runtime = "runc"
EOF
export CONTAINERS_CONF=$CACHE/containers.conf
podman info >/dev/null 2>&1 || die "podman info fails: $(podman info 2>&1 | tail -n 3)"

# ---- 2. base image -------------------------------------------------------------------------
# The Debian mirror of this machine's apt sources: one-line sources.list entries, then deb822
# *.sources stanzas, whichever names the plain "bookworm" suite first.
apt_mirror() {
  local f
  for f in /etc/apt/sources.list /etc/apt/sources.list.d/*.list; do
    [[ -r $f ]] || continue
    awk '$1 == "deb" { i = 2; if ($i ~ /^\[/) while ($i !~ /\]$/) ++i; if ($i ~ /^\[/ || $i ~ /\]$/) ++i;
                       if ($(i + 1) == "bookworm") { print $i; exit } }' "$f"
  done
  for f in /etc/apt/sources.list.d/*.sources; do
    [[ -r $f ]] || continue
    awk 'BEGIN { RS = ""; FS = "\n" }
         { uri = ""; deb = 0; suite = 0; off = 0
           for (i = 1; i <= NF; ++i) {
             if ($i ~ /^Types:/ && $i ~ /[ \t]deb([ \t]|$)/) deb = 1
             if ($i ~ /^Suites:/ && $i ~ /[ \t]bookworm([ \t]|$)/) suite = 1
             if ($i ~ /^Enabled:[ \t]*no/) off = 1
             if ($i ~ /^URIs:/) { split($i, u, /[ \t]+/); uri = u[2] } }
           if (deb && suite && !off && uri != "") { print uri; exit } }' "$f"
  done
}

if ! podman image exists "$BASE"; then
  if ! podman image exists localhost/debian:bookworm; then
    rootfs=$CACHE/rootfs-bookworm
    if [[ ! -f $rootfs/.complete ]]; then
      mirror=${CONICA_DEBIAN_MIRROR:-$(apt_mirror | head -n 1)}
      [[ -n $mirror ]] || die "no bookworm mirror in /etc/apt/sources.list{,.d}; set CONICA_DEBIAN_MIRROR"
      say "debootstrap bookworm from $mirror into $rootfs"
      rm -rf "$rootfs"
      t0=$(date +%s)
      timeout 900 debootstrap --variant=minbase bookworm "$rootfs" "$mirror" >"$WORK/debootstrap.log" 2>&1 ||
        { tail -n 20 "$WORK/debootstrap.log" >&2; die "debootstrap failed"; }
      # Apt settings the host needs for this mirror (e.g. an archive snapshot whose Release files
      # are past their Valid-Until) apply inside the image too.
      for c in /etc/apt/apt.conf.d/*; do
        grep -q -E 'Check-Valid-Until|Check-Date|Proxy' "$c" 2>/dev/null &&
          grep -h -E 'Check-Valid-Until|Check-Date|Proxy' "$c" >>"$rootfs/etc/apt/apt.conf.d/99conica-host"
      done
      rm -rf "$rootfs"/var/cache/apt/archives/*.deb "$rootfs"/var/lib/apt/lists/*
      touch "$rootfs/.complete"
      say "debootstrap took $(($(date +%s) - t0)) s"
    fi
    tar -C "$rootfs" --exclude=./.complete -c . |
      podman import --change 'CMD ["/bin/bash"]' - localhost/debian:bookworm >"$WORK/import.log" 2>&1 ||
      { cat "$WORK/import.log" >&2; die "podman import failed"; }
  fi
  podman tag localhost/debian:bookworm "$BASE"
fi
podman image exists "$BASE" || die "base image $BASE missing"

# ---- 3. build ------------------------------------------------------------------------------
say "building $IMAGE (podman build -f docker/Dockerfile -t $IMAGE .)"
t0=$(date +%s)
timeout 2400 podman build -f docker/Dockerfile -t "$IMAGE" . >"$WORK/build.log" 2>&1 ||
  { tail -n 40 "$WORK/build.log" >&2; die "podman build failed"; }
build_s=$(($(date +%s) - t0))
size=$(podman image inspect --format '{{.Size}}' "$IMAGE")
say "built in ${build_s} s, image $((size / 1000000)) MB"

# ---- 4. server -----------------------------------------------------------------------------
for p in $P_PROBE $P_STATE $P_CONTROL; do
  (exec 3<>"/dev/tcp/127.0.0.1/$p") 2>/dev/null && die "127.0.0.1:$p is in use; set CONICA_PORT_BASE"
done
podman run -d --name "$NAME" \
  -p "127.0.0.1:$P_PROBE:5555" -p "127.0.0.1:$P_STATE:5556" -p "127.0.0.1:$P_CONTROL:5557" \
  "$IMAGE" --stats-seconds 0 --builtin cube \
  --probe-endpoint tcp://0.0.0.0:5555 --state-endpoint tcp://0.0.0.0:5556 \
  --control-endpoint tcp://0.0.0.0:5557 >/dev/null || die "podman run failed"
for _ in $(seq 100); do
  podman logs "$NAME" 2>&1 | grep -q serving && break
  [[ $(podman inspect --format '{{.State.Running}}' "$NAME") == true ]] || die "server exited: $(podman logs "$NAME" 2>&1 | tail -n 5)"
  sleep 0.1
done
podman logs "$NAME" 2>&1 | grep -q serving || die "server not serving after 10 s"
say "server: $(podman logs "$NAME" 2>&1 | grep -m1 serving | sed 's/.*\] //')"

# ---- 5. probes -----------------------------------------------------------------------------
# Clients: the host's build/bin when present, else the image's on the host network (still
# outside the server's container, through the published ports).
if [[ -x build/bin/conica-latency && -x build/bin/conica-probe ]]; then
  latency=(build/bin/conica-latency) probe=(build/bin/conica-probe) where="host build/bin"
else
  client=(podman run --rm --network host --entrypoint)
  latency=("${client[@]}" conica-latency "$IMAGE") probe=("${client[@]}" conica-probe "$IMAGE")
  where="image clients on the host network"
fi
say "conica-latency from outside ($where): 2 s at 1 kHz"
timeout 60 "${latency[@]}" --endpoint "tcp://127.0.0.1:$P_PROBE" \
  --control-endpoint "tcp://127.0.0.1:$P_CONTROL" --seconds 2 >"$WORK/latency.txt" 2>&1 ||
  { cat "$WORK/latency.txt" >&2; die "conica-latency failed"; }
sed 's/^/  /' "$WORK/latency.txt"
line=$(grep -E '^p50_us=' "$WORK/latency.txt" | tail -n 1)
[[ -n $line ]] || die "no p50_us= line from conica-latency"
sent=$(sed -E 's/.*sent=([0-9]+).*/\1/' <<<"$line")
lost=$(sed -E 's/.*lost=([0-9]+).*/\1/' <<<"$line")
((sent >= 1000)) || die "only $sent updates sent in 2 s"
((lost * 100 <= sent)) || die "$lost of $sent round trips lost (more than 1 %)"

say "conica-probe from outside ($where): press 6 mm into the cube"
timeout 60 "${probe[@]}" --endpoint "tcp://127.0.0.1:$P_PROBE" --script press --depth 0.006 \
  --hold 0.5 --realtime -o - >"$WORK/press.csv" 2>"$WORK/probe.txt" ||
  { cat "$WORK/probe.txt" >&2; die "conica-probe failed"; }
cat "$WORK/probe.txt" | sed 's/^/  /'
peak=$(awk -F, 'NR == 1 { for (i = 1; i <= NF; ++i) c[$i] = i; next }
                { if ($c["fz"] > p) p = $c["fz"] } END { printf "%.6f", p + 0 }' "$WORK/press.csv")
awk -v p="$peak" 'BEGIN { exit !(p > 0) }' || die "no upward force while pressing (peak fz $peak N)"
say "peak fz $peak N over $(($(wc -l <"$WORK/press.csv") - 1)) replies"

say "conica-probe in a second container (host network) against the published port"
timeout 60 podman run --rm --network host --entrypoint conica-probe "$IMAGE" \
  --endpoint "tcp://127.0.0.1:$P_PROBE" --script press --depth 0.006 --hold 0.2 -o /dev/null \
  2>"$WORK/probe2.txt" >/dev/null || { cat "$WORK/probe2.txt" >&2; die "containerised conica-probe failed"; }
grep -q -E 'max \|F\| [0-9.]*[1-9]' "$WORK/probe2.txt" || die "containerised probe saw no force: $(cat "$WORK/probe2.txt")"
sed 's/^/  /' "$WORK/probe2.txt"

# ---- 6. stop -------------------------------------------------------------------------------
timeout 30 podman stop -t 10 "$NAME" >/dev/null || die "podman stop failed"
podman logs "$NAME" >"$WORK/server.log" 2>&1 || true
grep -q "stopped after" "$WORK/server.log" || die "server did not shut down cleanly on SIGTERM"
say "server: $(grep -m1 'stopped after' "$WORK/server.log" | sed 's/.*\] //')"
podman rm "$NAME" >/dev/null

# ---- optional: compose ---------------------------------------------------------------------
if [[ ${CONICA_DOCKER_COMPOSE:-0} == 1 ]]; then
  command -v podman-compose >/dev/null || die "CONICA_DOCKER_COMPOSE=1 but podman-compose is not installed"
  say "podman-compose: server + scripted probe"
  export CONICA_PROBE_PORT=$P_PROBE CONICA_STATE_PORT=$P_STATE CONICA_CONTROL_PORT=$P_CONTROL
  compose=(podman-compose -p conica-test -f docker/compose.yaml)
  timeout 120 "${compose[@]}" up --no-build --abort-on-container-exit >"$WORK/compose.log" 2>&1 || true
  timeout 60 "${compose[@]}" down >/dev/null 2>&1 || true
  podman network rm conica-test_default >/dev/null 2>&1 || true  # podman-compose 1.0 leaves it
  grep -q -E 'max \|F\| [0-9.]*[1-9]' "$WORK/compose.log" ||
    { tail -n 30 "$WORK/compose.log" >&2; die "compose probe saw no force"; }
  grep -E 'conica-probe: [0-9]+ replies' "$WORK/compose.log" | sed 's/^/  /'
fi

say "PASS in $(($(date +%s) - t_start)) s (build ${build_s} s, image $((size / 1000000)) MB)"
say "latency: $line"
