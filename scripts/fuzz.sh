#!/usr/bin/env bash
# Builds the libFuzzer targets with clang (ASan + UBSan) and runs each for a bounded time: the g2o
# reader, the decoders of the messages robots send one another (fuzz/messages_fuzz.cc), the
# journal a restarted robot replays (fuzz/journal_fuzz.cc), the DDS samples a robot takes
# (fuzz/dds_samples_fuzz.cc), the
# template cache decoder (fuzz/template_cache_fuzz.cc), the perception cache decoder
# (fuzz/perception_cache_fuzz.cc) and the other text files a user hands moslam: worlds, TUM
# trajectories and sequences, YOLO labels, a robot's g2o file, class names, a robot's summary
# (fuzz/text_files_fuzz.cc).
# Usage: scripts/fuzz.sh [seconds per target, default 60]
# Exits non-zero when the fuzzer finds a crash, a sanitizer report, a leak or a timeout; the input
# that triggered it is saved under build-fuzz/artifacts/.
set -euo pipefail

seconds="${1:-60}"
if ! [[ "$seconds" =~ ^[1-9][0-9]*$ ]]; then
  echo "usage: $0 [seconds > 0]" >&2
  exit 2
fi

repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="$repo/build-fuzz"
datasets="${MOSLAM_DATASETS_DIR:-$repo/../shared/datasets}"
CC_BIN="${CC_FUZZ:-clang}"
CXX_BIN="${CXX_FUZZ:-clang++}"

cmake -S "$repo" -B "$build" -G Ninja \
  -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_C_COMPILER="$CC_BIN" -DCMAKE_CXX_COMPILER="$CXX_BIN" \
  -DMOSLAM_BUILD_FUZZ=ON -DMOSLAM_BUILD_TESTS=OFF -DMOSLAM_BUILD_BENCH=OFF >/dev/null
cmake --build "$build" --target g2o_reader_fuzz messages_fuzz template_cache_fuzz journal_fuzz \
  perception_cache_fuzz text_files_fuzz dds_samples_fuzz

# Seed corpus, made fresh at every run from short snippets (datasets are never copied into the
# repository).
work="$(mktemp -d "${TMPDIR:-/tmp}/moslam-fuzz.XXXXXX")"
trap 'rm -rf "$work"' EXIT
corpus="$work/corpus"
mkdir -p "$corpus" "$build/artifacts"
tiny="$datasets/pgo/tinyGrid3D.g2o"
dm="$datasets/distributed-mapper/CogRob_distributed-mapper/distributed_mapper_core/data/blocks_world/2robots/0.g2o"
if [[ -f "$tiny" ]]; then
  head -n 4 "$tiny" >"$corpus/tiny_vertices"
  sed -n '1,3p;10,11p' "$tiny" >"$corpus/tiny_mixed"
fi
if [[ -f "$dm" ]]; then
  awk 'NR <= 2 || (/^EDGE/ && n++ < 2)' "$dm" >"$corpus/dm_symbols"
fi
ident="1 0 0 0 0 0 1 0 0 0 0 1 0 0 0 1 0 0 1 0 1"
printf '# comment\n\nVERTEX_SE3:QUAT 0 0 0 0 0 0 0 1\nEDGE_SE3:QUAT 0 1 1 0 0 0 0 0 1 %s\nEDGE_SE3:QUAT 1 0 1 0 0 0 0 0 1 %s\n' \
  "$ident" "$ident" >"$corpus/edges"
printf 'EDGE_SE3:QUAT 0 1 1 0 0 0 0 0 1 1 0 0 0 0 0 1 0 0 0 0 1 5 0 0 1 0 0 1 0 1\n' >"$corpus/coupled"
printf 'VERTEX_SE2 0 0 0 0\nFIX 0\n' >"$corpus/other_tags"
printf 'VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 0.5\nEDGE_SE2 0 1 1 0 0.5 10 0 0 10 0 100\n' >"$corpus/planar"

dict="$work/g2o.dict"
cat >"$dict" <<'DICT'
"VERTEX_SE3:QUAT"
"EDGE_SE3:QUAT"
"VERTEX_SE2"
"EDGE_SE2"
"FIX"
"#"
"nan"
"-inf"
"1e308"
"-0"
"18446744073709551615"
"18446744073709551616"
"6989586621679009792"
"7061644215716937730"
" 1 0 0 0 0 0 1 0 0 0 0 1 0 0 0 1 0 0 1 0 1"
DICT

# The messages: the first byte picks the decoder; a few valid headers as seeds.
mcorpus="$work/messages"
mkdir -p "$mcorpus"
printf '\x00\xd6\x01\x01\x01\x02\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00' >"$mcorpus/dgs_empty"
printf '\x03\xd9\x01\x01\x00\x02\x00\x00\x00\x01\x00\x00\x00\x00\x00\x00\x00' >"$mcorpus/weight_empty"
printf '\x04\xda\x01\x01\x00\x02\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00' >"$mcorpus/covariance_empty"
printf '\x05\x4f\x01\x01' >"$mcorpus/object_map_start"
# The refinement's piece messages (coarse, selector 2), each valid and one piece or block long:
# a matrix (reference point, a piece's centre, a 6 x 6 block), a residual, a solution.
zeros() { head -c "$1" /dev/zero; }
{ printf '\x02\xd8\x01\x03\x05\x00\x00\x00\x00\x00\x00\x00\x00\x06\x01\x03\x00'; zeros 24
  printf '\x01\x00\x00\x00\x00\x00\x00\x00'; zeros 24
  printf '\x01\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00'; zeros 288; } \
  >"$mcorpus/coarse_piece_matrix"
{ printf '\x02\xd8\x01\x03\x06\x00\x00\x00\x00\x00\x00\x00\x00\x06\x01\x00\x00'
  printf '\x01\x00\x00\x00\x00\x00\x00\x00'; zeros 48; } >"$mcorpus/coarse_piece_residual"
{ printf '\x02\xd8\x01\x03\x07\x00\x00\x00\x00\x00\x00\x00\x00\x06\x01\x00\x00'
  printf '\x01\x00\x00\x00\x00\x00\x00\x00\x00\x00'; zeros 48; } >"$mcorpus/coarse_piece_solution"
mdict="$work/messages.dict"
cat >"$mdict" <<'DICT'
"\xd6\x01"
"\xd7\x01"
"\xd8\x01"
"\xd9\x01"
"\xda\x01"
"\x4f\x01"
"\x00\x00\x00\x00\x00\x00\xf8\x7f"
"\x06\x00\x00\x00"
DICT

run_target() {  # name corpus dict max_len
  echo "fuzzing $1 for ${seconds}s"
  set +e
  "$build/fuzz/$1" "$2" -dict="$3" -max_total_time="$seconds" \
    -max_len="$4" -timeout=10 -rss_limit_mb=2048 -print_final_stats=1 \
    -artifact_prefix="$build/artifacts/$1-"
  local status=$?
  set -e
  if ((status != 0)); then
    echo "fuzz.sh: $1 failed (exit $status); reproducer in $build/artifacts/" >&2
    exit "$status"
  fi
}
run_target g2o_reader_fuzz "$corpus" "$dict" 4096
run_target messages_fuzz "$mcorpus" "$mdict" 4096

# Journals: one framed record (type 2, a start), a step record with one report, one with a robot's
# weights (robust solve), one with a robot's covariance (the separator check), a rendezvous
# event record (event 3, one pair added, one removed), an online group record (robots 1 and 3,
# one held pair), an online solve record (one pose, one held copy) and a departure record (robot
# 3 found gone at step 40).
jcorpus="$work/journal"
mkdir -p "$jcorpus"
printf '\x00\x01\x00\x00\x00\xa1\x8e\x0c\x3c\x02' >"$jcorpus/framed_start"
printf '\x01\x01\x00\x00\x00\x01\x01\x00\x00\x00\x03\x00\x00\x00\x00\x00\x00\xe0\x3f\x00\x00\x00\x00\x00\x00\xf0\x7f\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00' >"$jcorpus/step_one_report"
printf '\x01\x01\x00\x00\x00\x03\x02\x00\x00\x00\x10\x00\x00\x00\x00\x00\x00\xe0\x3f\x00\x00\x00\x00\x00\x00\xf0\x7f\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x01\x00\x00\x00\x00\x00\x00\x00\x00\xe0\x3f\x00\x00\x00\x00\x00\x00\xf0\x7f\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x01\x00\x18\x00\x00\x00\xd9\x01\x00\x00\x01\x00\x00\x00\x01\x00\x00\x00\x01\x00\x00\x00\x00\x00\x00\x00\x00\x00\xe0\x3f\x00\x00' >"$jcorpus/step_weights"
printf '\x01\x01\x00\x00\x00\x03\x02\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\xe0\x3f\x00\x00\x00\x00\x00\x00\xf0\x7f\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x01\x00\x20\x00\x00\x00\x00\x00\x00\xe0\x3f\x00\x00\x00\x00\x00\x00\xf0\x7f\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x01\x00\xb8\x00\x00\x00\xda\x01\x01\x00\x00\x00\x00\x00\x06\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\xf0\x3f\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\xf0\x3f\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\xf0\x3f\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\xf0\x3f\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\xf0\x3f\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\xf0\x3f' >"$jcorpus/step_covariance"
printf '\x02\x03\x00\x00\x00\x01\x00\x00\x00\x01\x00\x00\x00\x02\x00\x00\x00\x01\x00\x00\x00\x04\x00\x00\x00\x05\x00\x00\x00' >"$jcorpus/event_pair_removed"
printf '\x03\x05\x00\x00\x00\x02\x00\x01\x00\x03\x00\x01\x00\x00\x00\x01\x00\x01\x04\x00\x00\x00\x00\x00\x00\x00\x04\x00\x01\x02\x00\x00\x00\x00\x00\x00\x00\x03\x02\x00\x00\x00\x00\x00\x00\x00\x00\x00\xf0\x3f\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\xf0\x3f\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\xf0\x3f\x00\x00\x00\x00\x00\x00\xe0\x3f\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00' >"$jcorpus/group_held_pair"
printf '\x04\x05\x00\x00\x00\x01\x00\x00\x00\x01\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\xf0\x3f\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\xf0\x3f\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\xf0\x3f\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x01\x00\x00\x00\x04\x00\x01\x02\x00\x00\x00\x00\x00\x00\x00\x05\x00\x00\x00\x00\x00\x00\x00\x00\x00\xf0\x3f\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\xf0\x3f\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\xf0\x3f\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\xf0\x3f\x00\x00\x00\x00\x00\x00\x00\x00\x07\x00\x00\x00\x05\x00\x00\x00\x03\x00\x00\x00\x28\x00\x00\x00\x02\x00\x00\x00\x01\x00\x00\x00\x01' >"$jcorpus/solve_one_pose_one_copy"
printf '\x05\x03\x00\x28\x00\x00\x00' >"$jcorpus/left_robot"
# A node journal's records after its header (u16 length, bytes): a start, a team of 0 and 1, a
# departure of robot 1 at step 1, the end.
printf '\x06\x01\x00\x02\x07\x00\x03\x02\x00\x00\x00\x01\x00\x07\x00\x05\x01\x00\x01\x00\x00\x00\x01\x00\x07' >"$jcorpus/node_journal"
jdict="$work/journal.dict"
cat >"$jdict" <<'DICT'
"\x00\x00\x00\x00\x00\x00\xf0\x7f"
"\x00\x00\x00\x00\x00\x00\xf8\x7f"
"\xd6\x01"
"\xd8\x01"
"\xd9\x01"
"\xda\x01"
"\x01\x00\x00\x00"
DICT
run_target journal_fuzz "$jcorpus" "$jdict" 4096

# DDS samples as Cyclone DDS receives them: one valid sample of each topic type, written by the
# target itself (MOSLAM_FUZZ_WRITE_SEEDS), is where the fuzzer starts.
dcorpus="$work/dds"
mkdir -p "$dcorpus"
MOSLAM_FUZZ_WRITE_SEEDS="$dcorpus" "$build/fuzz/dds_samples_fuzz"
ddict="$work/dds.dict"
cat >"$ddict" <<'DICT'
"\x00\x00\x00\x00\x00\x00\xf0\x3f"
"\x00\x00\x00\x00\x00\x00\xf8\x7f"
"\x00\x00\x00\x00\x00\x00\xf0\x7f"
"\x06\x00\x00\x00chair\x00"
"\xff\xff\xff\xff"
DICT
run_target dds_samples_fuzz "$dcorpus" "$ddict" 4096

# Template cache files (without their checksum, which the harness appends): a header that asks
# for label "chair" and holds a few points.
tcorpus="$work/templates"
mkdir -p "$tcorpus"
printf 'MOSLTPL2\x01\x00\x00\x00\x00\x00\x00\x00\x05\x00\x00\x00chair' >"$tcorpus/header"
{  # a whole template: the default FeatureConfig, 10 points, 10 keypoints, their features
  cat "$tcorpus/header"
  printf '\x7b\x14\xae\x47\xe1\x7a\x94\x3f\x7b\x14\xae\x47\xe1\x7a\xa4\x3f'
  printf '\xec\x51\xb8\x1e\x85\xeb\xb1\x3f\xb8\x1e\x85\xeb\x51\xb8\x9e\x3f'
  printf '\xb8\x1e\x85\xeb\x51\xb8\x9e\x3f'
  for part in points keypoints; do
    printf '\x0a\x00\x00\x00'
    for i in 0 1 2 3 4 5 6 7 8 9; do
      printf '\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00'
      printf '\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x80\x3f\x10\x20\x30\xff'
    done
  done
  head -c 10000 /dev/zero
} >"$tcorpus/whole"
tdict="$work/templates.dict"
cat >"$tdict" <<'DICT'
"MOSLTPL2"
"\x05\x00\x00\x00chair"
"\x7b\x14\xae\x47\xe1\x7a\x94\x3f"
"\x7b\x14\xae\x47\xe1\x7a\xa4\x3f"
"\xec\x51\xb8\x1e\x85\xeb\xb1\x3f"
"\xb8\x1e\x85\xeb\x51\xb8\x9e\x3f"
"\x00\x00\x80\x3f"
"\x0a\x00\x00\x00"
DICT
run_target template_cache_fuzz "$tcorpus" "$tdict" 65536

# Perception cache files (without their checksum, which the harness appends): one robot with two
# poses, the second with a chair (identity rotation and information, object id 3), the 16
# metrics and a report.
pcorpus="$work/perceived"
mkdir -p "$pcorpus"
f64() {  # the little-endian bytes of a few doubles
  case "$1" in
    0) printf '\x00\x00\x00\x00\x00\x00\x00\x00' ;;
    1) printf '\x00\x00\x00\x00\x00\x00\xf0\x3f' ;;
    1.5) printf '\x00\x00\x00\x00\x00\x00\xf8\x3f' ;;
    -2) printf '\x00\x00\x00\x00\x00\x00\x00\xc0' ;;
    100) printf '\x00\x00\x00\x00\x00\x00\x59\x40' ;;
  esac
}
{
  printf 'MOSLPRC1\x2a\x00\x00\x00\x00\x00\x00\x00'  # fingerprint 42
  printf '\x01\x00\x00\x00\x02\x00\x00\x00\x00\x00\x00\x00\x01\x00\x00\x00'
  printf '\x05\x00\x00\x00chair'
  for i in 0 1 2; do for j in 0 1 2; do if ((i == j)); then f64 1; else f64 0; fi; done; done
  f64 1.5; f64 -2; f64 1
  for i in 0 1 2 3 4 5; do for j in 0 1 2 3 4 5; do if ((i == j)); then f64 100; else f64 0; fi; done; done
  printf '\x03\x00\x00\x00\x10\x00\x00\x00'
  for k in $(seq 16); do f64 1.5; done
  printf '\x04\x00\x00\x00ok\n\n'
} >"$pcorpus/one_chair"
printf 'MOSLPRC1\x2a\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x00\x10\x00\x00\x00' >"$pcorpus/no_robot_no_metrics"
pdict="$work/perceived.dict"
cat >"$pdict" <<'DICT'
"MOSLPRC1"
"\x05\x00\x00\x00chair"
"\x00\x00\x00\x00\x00\x00\xf0\x3f"
"\x00\x00\x00\x00\x00\x00\xf8\x7f"
"\x00\x00\x00\x00\x00\x00\xf0\x7f"
"\x10\x00\x00\x00"
"\xff\xff\xff\xff"
DICT
run_target perception_cache_fuzz "$pcorpus" "$pdict" 65536

# Text files: the first byte picks the reader (text_files_fuzz.cc: 0 world, 1 TUM trajectory, 2
# TUM sequence with bit 0x10 a camera file and 0x20 ground truth, its texts cut at NULs, 3 YOLO
# labels, 4 a robot's g2o file, 5 class names, 6 a robot's summary.json, bit 0x10 its arrays
# optional; modulo 7).
xcorpus="$work/text"
mkdir -p "$xcorpus"
printf '\x00{"format": "moslam-world", "version": 1, "name": "w", "classes": [{"label": "chair", "extent": [0.5, 0.5, 0.9]}], "objects": [{"id": 0, "label": "chair", "translation": [1, 2, 0], "rotation": [0, 0, 0, 1]}], "rooms": [{"name": "r", "min": [0, 0], "max": [4, 4]}], "navigation": {"nodes": [[1, 1], [3, 3]], "edges": [[0, 1]]}}' >"$xcorpus/world"
printf '\x01# timestamp tx ty tz qx qy qz qw\n0 0 0 0 0 0 0 1\n1 1 0 0 0 0 0.7071 0.7071\n' >"$xcorpus/trajectory"
printf '\x33# fx fy cx cy width height depth_scale\n160 160 159.5 119.5 320 240 5000\0# rgb\n0.000000 rgb/0.000000.png\n0.100000 rgb/0.100000.png\n\x000.000000 depth/0.000000.png\n0.100000 depth/0.100000.png\n\x000.000000 0 0 0 0 0 0 1\n0.100000 0.1 0 0 0 0 0 1\n' >"$xcorpus/sequence"
printf '\x03\x30 0.5 0.5 0.25 0.4\n1 0.1 0.9 0.05 0.05\n' >"$xcorpus/labels"
printf '\x04VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1\nEDGE_SE3:QUAT 0 1 1 0 0 0 0 0 1 1 0 0 0 0 0 1 0 0 0 0 1 0 0 0 1 0 0 1 0 1\nEDGE_SE3:QUAT 0 7061644215716937730 1 0 0 0 0 0 1 1 0 0 0 0 0 1 0 0 0 0 1 0 0 0 1 0 0 1 0 1\n' >"$xcorpus/robot_file"
printf '\x05person\r\nchair\n\n  dining table \t\n' >"$xcorpus/class_names"
printf '\x06{"pose_rounds": 7, "refine_final_cost": 2.94, "solves": [{"step": 3, "robots": [0, 2], "dds_sent_bytes": 100}], "rendezvous": [{"alpha": 0}], "shared": [[0, 1, 2, 3]]}' >"$xcorpus/summary"
xdict="$work/text.dict"
cat >"$xdict" <<'DICT'
"\"format\""
"\"moslam-world\""
"\"rotation\""
"\"translation\""
"\"navigation\""
"[0, 0, 0, 1]"
"1e308"
"-1e-320"
"nan"
"inf"
"#"
"\x00"
"VERTEX_SE3:QUAT"
"EDGE_SE3:QUAT"
"18446744073709551616"
"-9223372036854775809"
DICT
run_target text_files_fuzz "$xcorpus" "$xdict" 4096
echo "fuzz.sh: no crash in ${seconds}s per target"
