#!/usr/bin/env bash
# Installs what training/train_detector.py needs (Debian's torch and onnx, CPU only). Only for
# retraining the detector: building, testing and running moslam do not need it
# (scripts/setup.sh). Non-interactive and idempotent.
set -euo pipefail

PACKAGES=(python3 python3-numpy python3-pil python3-torch python3-onnx)

missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done

if ((${#missing[@]})); then
  SUDO=""
  [[ $(id -u) -ne 0 ]] && SUDO="sudo"
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get update -q
  $SUDO apt-get install -y -q --no-install-recommends "${missing[@]}"
fi
# Debian's interpreter: a python3 earlier on PATH may not see Debian's modules.
/usr/bin/python3 -c "import numpy, PIL, torch, onnx" 
echo "setup-training: ${PACKAGES[*]} present (run the training with /usr/bin/python3)"
