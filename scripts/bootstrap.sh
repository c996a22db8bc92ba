#!/usr/bin/env bash
# Create the project's virtual environment and install jointctl with its pinned
# dependencies. Installs Debian's python3-venv first when it is missing.
set -euo pipefail
PYTHON=${PYTHON:-/usr/bin/python3}
VENV=${VENV:-.venv}

as_root() {
  if [ "$(id -u)" = 0 ]; then "$@"; elif command -v sudo >/dev/null; then sudo "$@"; else
    echo "bootstrap: need root to run: $*" >&2; return 1; fi
}

if ! "$PYTHON" -c 'import ensurepip, venv' 2>/dev/null; then
  echo "bootstrap: installing python3-venv"
  as_root apt-get update -q
  DEBIAN_FRONTEND=noninteractive as_root apt-get install -y -q --no-install-recommends python3-venv
fi

if [ ! -x "$VENV/bin/python" ]; then
  echo "bootstrap: creating $VENV from $PYTHON"
  "$PYTHON" -m venv --system-site-packages "$VENV"
fi
"$VENV/bin/python" -m pip install -q --upgrade "pip>=23"
"$VENV/bin/python" -m pip install -q -e ".[test]"
# The compiled cycle's kernels: numba compiles them once (a few seconds) into its cache folder
# (~/.cache/jointctl/kernels/, see src/jointctl/jit.py), so that the first run does not wait.
"$VENV/bin/python" -c 'from jointctl.scenario.session import Session; from jointctl.scenario.spec import load_scenario
s = Session(load_scenario("one_dof_step")); s.run(0.001)
from jointctl.metrics.step_loop import HoldingEffort, JointLoop
JointLoop(1.0, 1.0, 0.001, hold=HoldingEffort.zero(), p=1.0).run([0.0, 1.0])  # the step analysis'"'"'s model
from jointctl.commands.sources import StepSource
from jointctl.commands.sources_kernel import sample_times
sample_times(StepSource(0.0, 1.0, 0.5), [0.0, 1.0])
print("bootstrap: loop:", s.loop.mode, s.loop.mode_reason or "")'
echo "bootstrap: ready ($("$VENV/bin/python" -c 'import mujoco, numpy; print("mujoco", mujoco.__version__, "numpy", numpy.__version__)'))"
