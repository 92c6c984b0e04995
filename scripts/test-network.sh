#!/usr/bin/env bash
# Robot processes in network namespaces, on shaped links (the kernel here has no netem: rate with
# `tc ... tbf`, loss and cuts with iptables). Each robot gets a namespace and a veth link to a
# bridge in a hub namespace; every robot's egress is shaped.
#
#   scripts/test-network.sh [path/to/moslam]      (default: ${BUILD_DIR:-build}/apps/moslam)
#   env: MOSLAM_NET_RATE (100kbit), MOSLAM_NET_LOSS (0.01), MOSLAM_NET_DATA (pgo/tinyGrid3D.g2o),
#        MOSLAM_NET_HEARTBEAT (500ms; Cyclone's default is 100ms), MOSLAM_NET_CUT=0 to measure only
#
# 1. shaped: 3 robots (tinyGrid3D split in 3), 100 kbit/s and 1% random loss on every robot's
#    egress: the team completes and equals the in-process driver (1e-9). Prints the time to
#    solution and the bytes on the wire (veth counters: everything, discovery included) per DGS
#    round, beside the DDS payload and the in-process binary byte count.
# 2. scenario: the 3 robots of a simulated scenario (chairs25, MOSLAM_NET_POSES=30 poses each) on
#    the same shaped links: object SLAM in each process, the rendezvous over DDS, then DGS; the
#    team completes with the in-process pipeline's shared objects and estimate (1e-9). Prints the
#    bytes on the wire of the rendezvous phase (until every robot started the DGS: discovery and
#    the team join included) and per DGS round, the time to solution, and what sending point
#    clouds instead would cost (paper Table 3: K = 640x480 points x C = 32 B per frame, every frame
#    of alpha up to the rendezvous).
# 2b. online: the same 3 scenario robots with --online (a group solve at every rendezvous, maps
#    saved after each) on the same shaped links: every robot completes the mission, each saved map
#    equals the in-process twin's (1e-9); prints the bytes on the wire per group solve. Then the
#    same with --online --robust (robust group solves): also the same pairs set aside as the twin.
# 3. cut: the same 3 robots at 100 kbit/s without random loss; robot 1's link is cut both ways
#    for 8 s in the middle of the pose stage (longer than the 5 s participant lease: the peers
#    see it gone, then back): the team completes, equal to the in-process result.
# Skips (exit 77) unless root with `ip netns`, tc and iptables. Cleans up after itself (trap).
# DDS domains 60..69 (tests: 40..59).
set -euo pipefail
cd "$(dirname "$0")/.."
MOSLAM=${1:-${BUILD_DIR:-build}/apps/moslam}
MOSLAM=$(realpath "$MOSLAM")
DATASETS=${MOSLAM_DATASETS_DIR:-$(realpath ../shared/datasets)}
RATE=${MOSLAM_NET_RATE:-100kbit}
LOSS=${MOSLAM_NET_LOSS:-0.01}
NET_DATA=${MOSLAM_NET_DATA:-pgo/tinyGrid3D.g2o}  # single-robot file under $DATASETS, split in 3
NET_POSES=${MOSLAM_NET_POSES:-30}                # poses per robot of the scenario case
CUT_TEST=${MOSLAM_NET_CUT:-1}                    # 0: measure only (skip the cut test)
HEARTBEAT=${MOSLAM_NET_HEARTBEAT:-500ms}         # Cyclone Internal/HeartbeatInterval
N=3

skip() { echo "test-network: SKIP: $*"; exit 77; }
[[ $(id -u) -eq 0 ]] || skip "not root (namespaces, tc and iptables need root)"
command -v ip >/dev/null || skip "no ip (iproute2)"
command -v tc >/dev/null || skip "no tc (iproute2)"
command -v iptables >/dev/null || skip "no iptables"
[[ -x $MOSLAM ]] || { echo "test-network: no moslam binary at $MOSLAM" >&2; exit 1; }

TAG="m$$"                 # unique names: namespaces and veths of this run
WORK=$(mktemp -d /tmp/moslam_net_XXXXXX)
NAMESPACES=()
PIDS=()
cleanup() {
  for p in "${PIDS[@]}"; do kill "$p" 2>/dev/null || true; done
  for p in "${PIDS[@]}"; do wait "$p" 2>/dev/null || true; done
  for ns in "${NAMESPACES[@]}"; do ip netns del "$ns" 2>/dev/null || true; done
  rm -rf "$WORK"
}
trap cleanup EXIT

ip netns add "${TAG}probe" 2>/dev/null || skip "cannot create network namespaces"
ip netns del "${TAG}probe"

# Hub with a bridge; robot i in namespace ${TAG}r$i, address 10.77.0.(i+1), interface v$i.
setup_net() {
  local hub="${TAG}h"
  ip netns add "$hub"; NAMESPACES+=("$hub")
  ip -n "$hub" link add br0 type bridge
  ip -n "$hub" link set br0 up
  ip -n "$hub" link set lo up
  for ((i = 0; i < N; i++)); do
    local ns="${TAG}r$i"
    ip netns add "$ns"; NAMESPACES+=("$ns")
    ip link add "${TAG}a$i" type veth peer name "${TAG}b$i"
    ip link set "${TAG}a$i" netns "$ns"
    ip link set "${TAG}b$i" netns "$hub"
    ip -n "$ns" link set "${TAG}a$i" name "v$i"
    ip -n "$hub" link set "${TAG}b$i" master br0
    ip -n "$hub" link set "${TAG}b$i" up
    ip -n "$ns" addr add "10.77.0.$((i + 1))/24" dev "v$i"
    ip -n "$ns" link set lo up
    ip -n "$ns" link set "v$i" up
  done
}

shape() {  # rate and loss on every robot's egress
  for ((i = 0; i < N; i++)); do
    ip netns exec "${TAG}r$i" tc qdisc replace dev "v$i" root tbf rate "$RATE" burst 1600 latency 500ms
    ip netns exec "${TAG}r$i" iptables -A OUTPUT -o "v$i" -m statistic --mode random \
      --probability "$LOSS" -j DROP
  done
}

config() {  # config <robot> <domain>: unicast peers, one participant (index 0) per namespace
  local i=$1 d=$2 peers="" p0
  p0=$((7400 + 250 * d + 10))
  for ((k = 0; k < N; k++)); do
    peers+="<Peer address=\"10.77.0.$((k + 1)):$p0\"/>"
  done
  # Heartbeats every 500 ms instead of 100 ms: on a 100 kbit/s link with a 500 ms queue, samples
  # still queued were NACKed and resent (measured: half the bytes and time, tinyGrid3D).
  echo "<CycloneDDS><Domain id=\"any\"><General><Interfaces><NetworkInterface name=\"v$i\"/></Interfaces><AllowMulticast>false</AllowMulticast></General><Internal><HeartbeatInterval min=\"100ms\" minsched=\"100ms\" max=\"2s\">$HEARTBEAT</HeartbeatInterval></Internal><Discovery><ParticipantIndex>auto</ParticipantIndex><MaxAutoParticipantIndex>1</MaxAutoParticipantIndex><SPDPInterval>1s</SPDPInterval><LeaseDuration>5s</LeaseDuration><Peers>$peers</Peers></Discovery></Domain></CycloneDDS>"
}

tx_bytes() {  # total bytes sent by the robots' interfaces
  local total=0
  for ((i = 0; i < N; i++)); do
    total=$((total + $(ip netns exec "${TAG}r$i" cat "/sys/class/net/v$i/statistics/tx_bytes")))
  done
  echo $total
}
tx_packets() {
  local total=0
  for ((i = 0; i < N; i++)); do
    total=$((total + $(ip netns exec "${TAG}r$i" cat "/sys/class/net/v$i/statistics/tx_packets")))
  done
  echo $total
}

start_robots() {  # start_robots <data> <domain> <out>
  local data=$1 d=$2 out=$3
  PIDS=()
  for ((i = 0; i < N; i++)); do
    mkdir -p "$out/robot$i"
    ip netns exec "${TAG}r$i" env CYCLONEDDS_URI="$(config "$i" "$d")" \
      "$MOSLAM" robot --robot "$i" --data "$data" --domain "$d" --out "$out/robot$i" \
      --progress --json >"$out/robot$i/stdout" 2>"$out/robot$i/log.txt" &
    PIDS+=($!)
  done
}

start_scenario_robots() {  # start_scenario_robots <domain> <out>
  local d=$1 out=$2
  PIDS=()
  for ((i = 0; i < N; i++)); do
    mkdir -p "$out/robot$i"
    ip netns exec "${TAG}r$i" env CYCLONEDDS_URI="$(config "$i" "$d")" \
      "$MOSLAM" robot --robot "$i" "${SCENARIO[@]}" --domain "$d" --out "$out/robot$i" \
      --progress --json >"$out/robot$i/stdout" 2>"$out/robot$i/log.txt" &
    PIDS+=($!)
  done
}

wait_robots() {  # every robot must exit 0
  local rc=0
  for i in "${!PIDS[@]}"; do
    if ! wait "${PIDS[$i]}"; then
      echo "test-network: robot $i failed:" >&2; tail -5 "$1/robot$i/log.txt" >&2; rc=1
    fi
  done
  PIDS=()
  return $rc
}

check_result() {  # check_result <data> <out> <label>: compare with the in-process driver
  local data=$1 out=$2 label=$3 json
  json=$("$MOSLAM" team --data "$data" --out "$out" --collect --json | tail -1)
  python3 - "$json" "$label" <<'EOF'
import json, sys
j = json.loads(sys.argv[1]); label = sys.argv[2]
assert j["ok"], f"{label}: a robot failed"
assert j["max_difference"] <= 1e-9, f"{label}: differs from the in-process driver by {j['max_difference']}"
print(f"test-network: {label}: OK, largest difference to the in-process driver "
      f"{j['max_difference']:.2g}, rounds {j['rotation_rounds']}+{j['pose_rounds']}")
EOF
  echo "$json" >"$out/team.json"
}

setup_net
"$MOSLAM" team --data "$DATASETS/$NET_DATA" --robots $N --out "$WORK/split" --prepare >/dev/null
DATA="$WORK/split/data"

# ---- 1. shaped links ------------------------------------------------------------------------
shape
OUT="$WORK/shaped"
bytes0=$(tx_bytes); packets0=$(tx_packets); t0=$(date +%s.%N)
start_robots "$DATA" 60 "$OUT"
wait_robots "$OUT"
t1=$(date +%s.%N); bytes1=$(tx_bytes); packets1=$(tx_packets)
check_result "$DATA" "$OUT" "$N robots, $RATE, loss $LOSS"
python3 - "$OUT/team.json" "$t0" "$t1" "$((bytes1 - bytes0))" "$((packets1 - packets0))" "$RATE" "$LOSS" <<'EOF'
import json, sys
j = json.load(open(sys.argv[1])); t0, t1 = float(sys.argv[2]), float(sys.argv[3])
wire, packets = int(sys.argv[4]), int(sys.argv[5])
rounds = j["rotation_rounds"] + j["pose_rounds"]
print(f"test-network: time to solution {t1 - t0:.1f} s on {sys.argv[6]} with loss {sys.argv[7]} "
      f"({rounds} DGS rounds)")
print(f"test-network: on the wire {wire} B in {packets} packets (all traffic, Ethernet frames), "
      f"{wire / rounds:.0f} B per round; DDS payload {j['dds_estimate_bytes'] + j['dds_status_bytes']} B "
      f"({(j['dds_estimate_bytes'] + j['dds_status_bytes']) / rounds:.0f} B per round: estimates "
      f"{j['dds_estimate_bytes']} B, status {j['dds_status_bytes']} B); in-process binary estimates "
      f"{j['in_process_bytes']} B ({j['in_process_bytes'] / rounds:.0f} B per round)")
EOF

# ---- 2. a simulated scenario: rendezvous and DGS on the shaped links ------------------------
SCENARIO=(--scenario chairs25 --robots "$N" --poses "$NET_POSES")
OUT="$WORK/scenario"
bytes0=$(tx_bytes); packets0=$(tx_packets); t0=$(date +%s.%N)
start_scenario_robots 62 "$OUT"
bytes_rdv=""
while :; do  # the rendezvous phase ends when every robot has started the DGS
  all=1
  for ((i = 0; i < N; i++)); do
    grep -q "^progress: rotation 0 " "$OUT/robot$i/stdout" 2>/dev/null || all=0
  done
  if ((all)); then
    bytes_rdv=$(tx_bytes); packets_rdv=$(tx_packets); t_rdv=$(date +%s.%N); break
  fi
  running=0
  for p in "${PIDS[@]}"; do kill -0 "$p" 2>/dev/null && running=1; done
  ((running)) || break
  sleep 0.1
done
wait_robots "$OUT"
t1=$(date +%s.%N); bytes1=$(tx_bytes); packets1=$(tx_packets)
[[ -n $bytes_rdv ]] || { echo "test-network: the robots never all reached the DGS" >&2; exit 1; }
json=$("$MOSLAM" team "${SCENARIO[@]}" --out "$OUT" --collect --json | tail -1)
python3 - "$json" "$OUT" "$t0" "$t_rdv" "$t1" "$bytes0" "$bytes_rdv" "$bytes1" "$packets0" \
  "$packets_rdv" "$packets1" "$RATE" "$LOSS" <<'EOF'
import glob, json, sys
j = json.loads(sys.argv[1]); out = sys.argv[2]
t0, t_rdv, t1 = map(float, sys.argv[3:6])
b0, b_rdv, b1, p0, p_rdv, p1 = map(int, sys.argv[6:12])
rate, loss = sys.argv[12], sys.argv[13]
label = f"scenario chairs25, {j['robots']} robots x {j['poses_per_robot']} poses, {rate}, loss {loss}"
assert j["ok"], f"{label}: a robot failed"
assert j["shared_objects_equal"], f"{label}: shared objects differ from the in-process pipeline"
assert j["max_difference"] <= 1e-9, f"{label}: differs from the in-process pipeline by {j['max_difference']}"
events = j["rendezvous_events"]; rounds = j["rotation_rounds"] + j["pose_rounds"]
print(f"test-network: {label}: OK, {events} rendezvous, {j['shared_objects']} shared objects "
      f"(in-process {j['in_process_shared_objects']}, the same pairs), largest difference "
      f"{j['max_difference']:.2g}, rounds {j['rotation_rounds']}+{j['pose_rounds']}")
print(f"test-network: time to solution {t1 - t0:.1f} s (rendezvous phase {t_rdv - t0:.1f} s, "
      f"DGS {t1 - t_rdv:.1f} s)")
print(f"test-network: rendezvous phase on the wire {b_rdv - b0} B in {p_rdv - p0} packets "
      f"({(b_rdv - b0) / events:.0f} B per rendezvous, discovery and join included); DDS payload "
      f"{j['rendezvous_dds_bytes']} B in {j['rendezvous_dds_samples']} samples "
      f"({j['rendezvous_dds_bytes'] / events:.0f} B per rendezvous); in-process encoding "
      f"{j['in_process_rendezvous_bytes']} B ({j['in_process_rendezvous_bytes'] / events:.0f} B per rendezvous)")
dgs_payload = j["dds_estimate_bytes"] + j["dds_status_bytes"]
print(f"test-network: DGS on the wire {b1 - b_rdv} B in {p1 - p_rdv} packets "
      f"({(b1 - b_rdv) / rounds:.0f} B per round); DDS payload {dgs_payload} B "
      f"({dgs_payload / rounds:.0f} B per round); in-process binary {j['in_process_bytes']} B "
      f"({j['in_process_bytes'] / rounds:.0f} B per round)")
# Point clouds instead (paper Table 3): alpha sends every frame up to the rendezvous.
K, C = 640 * 480, 32
frames = 0
for f in sorted(glob.glob(f"{out}/robot*/summary.json")):
    s = json.load(open(f))
    frames += sum(e["step"] + 1 for e in s["rendezvous"] if e["alpha"] == s["robot"])
pcd = frames * K * C
print(f"test-network: point clouds instead: {frames} frames x {K} points x {C} B = {pcd} B "
      f"({pcd / events:.3g} B per rendezvous, {pcd / (b_rdv - b0):.3g}x the rendezvous phase on "
      f"the wire; {pcd * 8 / 1e5:.0f} s at 100 kbit/s)")
EOF

# ---- 2b. online mapping: a group solve at every rendezvous, on the same shaped links ----------
online_case() {  # online_case <domain> <label> [extra flags of moslam robot/team]
  local d=$1 label=$2 json bytes0 packets0 t0 t1 bytes1 packets1
  shift 2
  OUT="$WORK/online$d"
  SCENARIO=(--scenario chairs25 --robots "$N" --poses "$NET_POSES" --online "$@")
  bytes0=$(tx_bytes); packets0=$(tx_packets); t0=$(date +%s.%N)
  start_scenario_robots "$d" "$OUT"
  wait_robots "$OUT"
  t1=$(date +%s.%N); bytes1=$(tx_bytes); packets1=$(tx_packets)
  json=$("$MOSLAM" team "${SCENARIO[@]}" --out "$OUT" --collect --json | tail -1)
  python3 - "$json" "$t0" "$t1" "$((bytes1 - bytes0))" "$((packets1 - packets0))" "$RATE" "$LOSS" \
    "$label" <<'EOF'
import json, sys
j = json.loads(sys.argv[1]); t0, t1 = float(sys.argv[2]), float(sys.argv[3])
wire, packets, rate, loss = int(sys.argv[4]), int(sys.argv[5]), sys.argv[6], sys.argv[7]
label = f"{sys.argv[8]} chairs25, {j['robots']} robots x {j['poses_per_robot']} poses, {rate}, loss {loss}"
assert j["ok"], f"{label}: a robot failed or its solves differ from the in-process twin"
assert j["group_solves"] > 0, f"{label}: no group solve"
assert j["max_difference"] <= 1e-9, f"{label}: differs from the in-process twin by {j['max_difference']}"
assert j["set_aside"] == j["in_process_set_aside"], f"{label}: pairs set aside differ from the twin's"
solves = j["group_solves"]
print(f"test-network: {label}: OK, {j['rendezvous_events']} rendezvous, {solves} group solves, "
      f"{j['maps_compared']} saved maps equal to the in-process twin (largest difference "
      f"{j['max_difference']:.2g}), {j['set_aside']} pairs set aside; mission {t1 - t0:.1f} s")
print(f"test-network: {sys.argv[8]} on the wire {wire} B in {packets} packets (all traffic, discovery "
      f"included), {wire / solves:.0f} B per group solve; DDS payload {j['dds_bytes_per_solve']:.0f} B "
      f"per group solve (objects {j['rendezvous_dds_bytes']} B, solves {j['solve_dds_bytes']} B in all); "
      f"point clouds instead, one frame per robot of the group: {j['point_cloud_bytes_per_solve']:.3g} B "
      f"per group solve ({j['point_cloud_bytes_per_solve'] * 8 / 1e5:.0f} s at 100 kbit/s)")
EOF
}
online_case 63 online
online_case 64 "online robust" --robust

# ---- 3. a cut link ----------------------------------------------------------------------------
if [[ $CUT_TEST == 0 ]]; then echo "test-network: cut test skipped (MOSLAM_NET_CUT=0)"; exit 0; fi
for ((i = 0; i < N; i++)); do  # the rate stays (a round takes ~0.2 s), no random loss
  ip netns exec "${TAG}r$i" iptables -F OUTPUT
done
OUT="$WORK/cut"
start_robots "$DATA" 61 "$OUT"
for _ in $(seq 1 600); do  # up to 60 s for robot 1 to reach pose round 10
  grep -q "^progress: pose 10 " "$OUT/robot1/stdout" 2>/dev/null && break
  sleep 0.1
done
grep -q "^progress: pose 10 " "$OUT/robot1/stdout" || { echo "test-network: robot 1 never reached pose round 10" >&2; exit 1; }
ip netns exec "${TAG}r1" iptables -I OUTPUT 1 -o v1 -j DROP
ip netns exec "${TAG}r1" iptables -I INPUT 1 -i v1 -j DROP
at_cut=$(grep -c "^progress: pose" "$OUT/robot1/stdout")
echo "test-network: robot 1's link cut at pose round $at_cut for 8 s"
sleep 8
ip netns exec "${TAG}r1" iptables -D OUTPUT -o v1 -j DROP
ip netns exec "${TAG}r1" iptables -D INPUT -i v1 -j DROP
wait_robots "$OUT"
check_result "$DATA" "$OUT" "link cut for 8 s during the pose stage"
pose_rounds=$(python3 -c "import json; print(json.load(open('$OUT/team.json'))['pose_rounds'])")
if ((at_cut >= pose_rounds)); then
  echo "test-network: the cut came after the end of the solve" >&2; exit 1
fi
# The cut outlasted the participant lease: the others saw robot 1 go and come back.
grep -q "robot 1 is gone" "$OUT/robot0/log.txt" || { echo "test-network: robot 0 never lost robot 1" >&2; exit 1; }
grep -q "robot 1 is back" "$OUT/robot0/log.txt" || { echo "test-network: robot 1 never came back for robot 0" >&2; exit 1; }
echo "test-network: all passed"
