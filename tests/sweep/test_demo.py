"""The demo report's sweep, run for real on a local cluster: the 1-DOF robot carrying 0 to 5 kg against theory."""

from __future__ import annotations

import math
import re

import pytest

from jointctl.sweep.demo import FOLDER, demo_section

pytestmark = pytest.mark.wall_clock  # it starts a local cluster's worker processes


def test_the_demo_sweep_reports_each_payload_beside_its_theory(tmp_path):
    section = demo_section(tmp_path)
    assert section.startswith("## Sweep: one_dof_step carrying a payload")
    rows = re.findall(r"^\| (\d) \| ([\d.]+) \| ([\d.]+) \| ([\d.]+) \| ([\d.]+) \| ([\d.]+) \| ([\d.]+) \| (yes|no) \|$",
                      section, flags=re.MULTILINE)
    assert [int(r[0]) for r in rows] == [0, 1, 2, 3, 4, 5]
    for payload, wn, wn_theory, zeta, zeta_theory, overshoot, overshoot_theory, passed in rows:
        m = 1.01 + int(payload)
        assert float(wn_theory) == pytest.approx(math.sqrt(400 / m), rel=1e-3)  # printed to 4 digits
        # The 1 kHz loop against the continuous theory: within ωn·dt (see tests/sweep/test_runner.py).
        assert float(wn) == pytest.approx(float(wn_theory), rel=2e-2)
        assert float(zeta) == pytest.approx(float(zeta_theory), rel=2e-2)
        # The overshoot reads a sampled peak off a 6 s record: within a point of exp(-πζ/√(1-ζ²)).
        assert float(overshoot) == pytest.approx(float(overshoot_theory), abs=1.0)
        assert (passed == "yes") == (float(overshoot) <= 60)
    assert f"]({FOLDER}/responses.png)" in section
    assert (tmp_path / FOLDER / "responses.png").stat().st_size > 10_000
    assert (tmp_path / FOLDER / "results.csv").is_file()
