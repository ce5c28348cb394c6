#!/usr/bin/env bash
# CI step: the suite on Ubuntu 24.04's library versions (python 3.12, numpy 1.26.4, OpenCV 4.6.0, numba 0.61.2)
# in a second venv (.venv-noble, .ci/noble-requirements.txt). Needs a python3.12 (PATH or pyenv).
set -euo pipefail
cd "$(dirname "$0")/.."
echo "== Ubuntu 24.04 library versions: make test-noble"
make test-noble
