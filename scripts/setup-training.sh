#!/usr/bin/env bash
# Installs what training/train_detector.py needs (Debian's torch and onnx, CPU only). Only for
# retraining the detector: building, testing and running moslam do not need it
# (scripts/setup.sh). Non-interactive and idempotent.
set -euo pipefail

PACKAGES=(python3 python3-numpy python3-pil python3-torch python3-onnx)

source "$(dirname "${BASH_SOURCE[0]}")/lib/debian-packages.sh"
install_debian_packages "${PACKAGES[@]}"
# Debian's interpreter: a python3 earlier on PATH may not see Debian's modules.
/usr/bin/python3 -c "import numpy, PIL, torch, onnx" 
echo "setup-training: ${PACKAGES[*]} present (run the training with /usr/bin/python3)"
