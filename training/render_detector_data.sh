#!/bin/bash
# Renders the detector's training set (TRAIN), held-out set (HELD) and model-selection set (VAL)
# in the YOLO layout (`moslam render --format yolo`: images/, labels/, ignore/, classes.txt).
# Usage: training/render_detector_data.sh [TRAIN_DIR] [HELD_DIR] [VAL_DIR]   (MOSLAM=path/to/moslam)
# (~10 min on the loaded 2-core machine; 7001 + 730 + 822 frames)
set -e
M=${MOSLAM:-build/apps/moslam}
TRAIN=${1:-data/detector/train}
HELD=${2:-data/detector/heldout}
VAL=${3:-data/detector/val}
C="--width 320 --height 240 --format yolo --min-labels 1"
# Training: generated worlds seeds 1-16, house trajectories 1-12, chairs25 1-10 (index blocks of
# 1000; seeds 1-8 / 1-6 / 1-5 were the first training set, the others were added at 30000+).
for s in 1 2 3 4 5 6 7 8; do
  $M render --scenario generated --robots 12 --poses 80 --frames-per-robot 40 --seed $s $C --out $TRAIN --first-index $(( (s-1)*1000 ))
done
for s in 1 2 3 4 5 6; do
  $M render --scenario house --robots 6 --poses 60 --frames-per-robot 30 --seed $s $C --out $TRAIN --first-index $(( 10000 + (s-1)*1000 ))
done
for s in 1 2 3 4 5; do
  $M render --scenario chairs25 --robots 6 --poses 40 --frames-per-robot 20 --seed $s $C --out $TRAIN --first-index $(( 20000 + (s-1)*1000 ))
done
for s in 9 10 11 12 13 14 15 16; do
  $M render --scenario generated --robots 12 --poses 80 --frames-per-robot 40 --seed $s $C --out $TRAIN --first-index $(( 30000 + (s-9)*1000 ))
done
for s in 7 8 9 10 11 12; do
  $M render --scenario house --robots 6 --poses 60 --frames-per-robot 30 --seed $s $C --out $TRAIN --first-index $(( 40000 + (s-7)*1000 ))
done
for s in 6 7 8 9 10; do
  $M render --scenario chairs25 --robots 6 --poses 40 --frames-per-robot 20 --seed $s $C --out $TRAIN --first-index $(( 50000 + (s-6)*1000 ))
done
# Held-out (the reported numbers): seeds 101-102 (new generated worlds, new chairs25 yaws; house =
# same layout, new trajectories, colours and noise).
for s in 101 102; do
  $M render --scenario generated --robots 12 --poses 80 --frames-per-robot 40 --seed $s $C --out $HELD --first-index $(( (s-101)*1000 ))
done
$M render --scenario house --robots 6 --poses 60 --frames-per-robot 30 --seed 101 $C --out $HELD --first-index 10000
$M render --scenario chairs25 --robots 6 --poses 40 --frames-per-robot 20 --seed 101 $C --out $HELD --first-index 20000
# Model selection (choosing between training runs; never reported as the result): seeds 201-202.
for s in 201 202; do
  $M render --scenario generated --robots 12 --poses 80 --frames-per-robot 40 --seed $s $C --out $VAL --first-index $(( (s-201)*1000 ))
done
$M render --scenario house --robots 6 --poses 60 --frames-per-robot 30 --seed 201 $C --out $VAL --first-index 10000
$M render --scenario chairs25 --robots 6 --poses 40 --frames-per-robot 20 --seed 201 $C --out $VAL --first-index 20000
echo "train: $(ls $TRAIN/images | wc -l) images, held-out: $(ls $HELD/images | wc -l), val: $(ls $VAL/images | wc -l)"
