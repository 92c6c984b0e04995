#!/bin/bash
# Renders the detector's training set (TRAIN), held-out set (HELD) and model-selection set (VAL)
# in the YOLO layout (`moslam render --format yolo`: images/, labels/, ignore/, classes.txt).
# Usage: training/render_detector_data.sh [TRAIN_DIR] [HELD_DIR] [VAL_DIR]   (MOSLAM=path/to/moslam)
# (~4 min on the 2-core machine; 13114 training frames, 730 held-out, 822 for model selection)
set -e
M=${MOSLAM:-build/apps/moslam}
TRAIN=${1:-data/detector/train}
HELD=${2:-data/detector/heldout}
VAL=${3:-data/detector/val}

# render OUT SCENARIO ROBOTS POSES FRAMES_PER_ROBOT FIRST_INDEX SEED...: one index block of 1000
# frames per seed, from FIRST_INDEX on.
render() {
  local out=$1 scenario=$2 robots=$3 poses=$4 frames=$5 index=$6
  shift 6
  for seed in "$@"; do
    "$M" render --scenario "$scenario" --robots "$robots" --poses "$poses" \
      --frames-per-robot "$frames" --seed "$seed" --width 320 --height 240 --format yolo \
      --min-labels 1 --out "$out" --first-index "$index"
    index=$(( index + 1000 ))
  done
}

# Training: generated worlds seeds 1-16, house trajectories 1-12, chairs25 1-10 (seeds 1-8 / 1-6
# / 1-5 were the first training set, the others were added at 30000+).
render "$TRAIN" generated 12 80 40     0 1 2 3 4 5 6 7 8
render "$TRAIN" house      6 60 30 10000 1 2 3 4 5 6
render "$TRAIN" chairs25   6 40 20 20000 1 2 3 4 5
render "$TRAIN" generated 12 80 40 30000 9 10 11 12 13 14 15 16
render "$TRAIN" house      6 60 30 40000 7 8 9 10 11 12
render "$TRAIN" chairs25   6 40 20 50000 6 7 8 9 10
# Third block (the fine-tuning of the 0.75-width model, models/detector/README.md): generated
# 17-22, house 23-26, chairs25 11-14, at 60000+.
render "$TRAIN" generated 12 80 40 60000 17 18 19 20 21 22
render "$TRAIN" house      6 60 30 70000 23 24 25 26
render "$TRAIN" chairs25   6 40 20 80000 11 12 13 14
# Fourth block (the second fine-tuning, models/detector/README.md): generated 23-30, house 27-32,
# chairs25 15-20, at 90000+.
render "$TRAIN" generated 12 80 40 90000 23 24 25 26 27 28 29 30
render "$TRAIN" house      6 60 30 100000 27 28 29 30 31 32
render "$TRAIN" chairs25   6 40 20 110000 15 16 17 18 19 20
# Held-out (the reported numbers): seeds 101-102 (new generated worlds, new chairs25 yaws; house =
# same layout, new trajectories, colours and noise).
render "$HELD" generated 12 80 40     0 101 102
render "$HELD" house      6 60 30 10000 101
render "$HELD" chairs25   6 40 20 20000 101
# Model selection (choosing between training runs; never reported as the result): seeds 201-202.
render "$VAL" generated 12 80 40     0 201 202
render "$VAL" house      6 60 30 10000 201
render "$VAL" chairs25   6 40 20 20000 201
echo "train: $(ls "$TRAIN"/images | wc -l) images, held-out: $(ls "$HELD"/images | wc -l), val: $(ls "$VAL"/images | wc -l)"
