#!/bin/bash
# Renders the detector training set (TRAIN) and the held-out set (HELD) in the YOLO layout.
# Usage: training/render_detector_data.sh [TRAIN_DIR] [HELD_DIR]   (MOSLAM=path/to/moslam)   (~5-8 min on the loaded machine)
set -e
M=${MOSLAM:-build/apps/moslam}
TRAIN=${1:-data/detector/train}
HELD=${2:-data/detector/heldout}
C="--width 320 --height 240 --format yolo --min-labels 1"
# Training: seeds 1-8 (generated), 1-6 (house trajectories), 1-5 (chairs25); index blocks of 1000.
for s in 1 2 3 4 5 6 7 8; do
  $M render --scenario generated --robots 12 --poses 80 --frames-per-robot 40 --seed $s $C --out $TRAIN --first-index $(( (s-1)*1000 ))
done
for s in 1 2 3 4 5 6; do
  $M render --scenario house --robots 6 --poses 60 --frames-per-robot 30 --seed $s $C --out $TRAIN --first-index $(( 10000 + (s-1)*1000 ))
done
for s in 1 2 3 4 5; do
  $M render --scenario chairs25 --robots 6 --poses 40 --frames-per-robot 20 --seed $s $C --out $TRAIN --first-index $(( 20000 + (s-1)*1000 ))
done
# Held-out: other seeds (new generated worlds, new chairs25 yaws; house = same layout, new
# trajectories, colours and noise).
for s in 101 102; do
  $M render --scenario generated --robots 12 --poses 80 --frames-per-robot 40 --seed $s $C --out $HELD --first-index $(( (s-101)*1000 ))
done
$M render --scenario house --robots 6 --poses 60 --frames-per-robot 30 --seed 101 $C --out $HELD --first-index 10000
$M render --scenario chairs25 --robots 6 --poses 40 --frames-per-robot 20 --seed 101 $C --out $HELD --first-index 20000
echo "train: $(ls $TRAIN/images | wc -l) images, held-out: $(ls $HELD/images | wc -l) images"
