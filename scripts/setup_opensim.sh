#!/usr/bin/env bash
# Install Pose2Sim, OpenSim and trc-data-reader (all from PyPI) in a virtual environment of their own, for
# `rmpl benchmark opensim_ik` (OpenSim scaling + inverse kinematics on rmpl's per-person TRC).
#
#   bash scripts/setup_opensim.sh [VENV]      # default VENV: <repo>/.venv-opensim
#
# Kept apart from rmpl's own venv: opensim's wheel is ~70 MB and Pose2Sim pulls in its own
# stack (openvino, rtmlib, PySide6, ...); rmpl itself never imports either.
# Idempotent: a venv that already has the pinned versions is left as it is. Needs Python
# >= 3.11 (opensim 4.6 ships CPython 3.11+ wheels for manylinux x86_64).
#
# Pose2Sim's console script does not start here; use its Python API instead:
#   VENV/bin/python -c "from Pose2Sim import Pose2Sim; Pose2Sim.kinematics()"
set -euo pipefail

POSE2SIM_VERSION=0.10.49
OPENSIM_VERSION=4.6
TRC_READER_VERSION=0.4.1  # trc-data-reader: tests/io/test_pose2sim.py reads rmpl's TRC with it

repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
venv="${1:-$repo/.venv-opensim}"
python="${PYTHON:-python3}"

have() {  # have VENV: true when the pinned versions import from VENV
    [ -x "$1/bin/python" ] || return 1
    "$1/bin/python" - "$POSE2SIM_VERSION" "$OPENSIM_VERSION" "$TRC_READER_VERSION" <<'EOF' 2>/dev/null
import sys
from importlib.metadata import version
import opensim  # noqa: F401  the native library loads
from Pose2Sim import Pose2Sim  # noqa: F401
import trc  # noqa: F401
want = {"pose2sim": sys.argv[1], "opensim": sys.argv[2], "trc-data-reader": sys.argv[3]}
sys.exit(0 if all(version(k) == v for k, v in want.items()) else 1)
EOF
}

if have "$venv"; then
    echo "already installed in $venv"
else
    if [ ! -x "$venv/bin/python" ]; then
        "$python" -m venv "$venv"
    fi
    "$venv/bin/python" -m pip install --quiet --upgrade pip
    "$venv/bin/python" -m pip install --quiet \
        "pose2sim==$POSE2SIM_VERSION" "opensim==$OPENSIM_VERSION" \
        "trc-data-reader==$TRC_READER_VERSION"
    have "$venv" || { echo "error: $venv does not import opensim / Pose2Sim" >&2; exit 1; }
fi

"$venv/bin/python" - <<'EOF'
import sys
from importlib.metadata import version

import opensim

print(f"python {sys.version.split()[0]} at {sys.executable}")
for name in ("pose2sim", "opensim", "trc-data-reader", "numpy", "pandas", "c3d"):
    print(f"{name} {version(name)}")
print(f"opensim library {opensim.GetVersionAndDate()}")
EOF
