"""Table 3.2's least-squares identification (eq. 3.24) against an independent transcription (issue 23).

The same logged trials (rhi's MuJoCo pushes, set up as `ch3.sysid_table_3_2` sets them up) go through
rhi's `identify` and through `tests/sysid_transcription.py`; Λ and B agree to 1e-8 (measured: 2e-10). A planted
difference (no low-pass) moves Λ by 0.5–0.8 %, so the comparison can fail.
"""

from __future__ import annotations

import numpy as np
import pytest
import sysid_transcription as st

from rhi.devices.model import device
from rhi.experiments.ch3.identification import BEFORE_CH3
from rhi.experiments.ch3.measures import POINTS, THESIS_Q
from rhi.experiments.identification import WINDOW, U, identify_case, trial_forces


def _case(name: str, i: int):
    """One case of Table 3.2 as `sysid_table_3_2` runs it (configuration "thesis"), 4 trials (its quick run)."""
    dev = device({"RHI": "rhi4", "PHANToM": "phantom"}[name])
    x, u = np.array(POINTS[i]), np.array(U)
    q_nom = dev.ik(x, np.array(THESIS_Q[i]), k_null=0.0) if name == "RHI" else dev.ik(x, np.full(dev.n, 0.3))
    q_start = dev.ik(x - BEFORE_CH3 * u, q_nom, k_null=0.0)
    return identify_case(dev, q_start, q_nom, x, label=f"{name} {i}", forces=trial_forces(4, 0), u=u)


@pytest.fixture(scope="module")
def cases():
    return {(n, i): _case(n, i) for n in ("RHI", "PHANToM") for i in (0, 1)}


def test_identified_lambda_equals_the_transcribed_eq_3_24_fit(cases):
    for (name, i), case in cases.items():
        lam, b = st.fit_eq_3_24(case.records, point=POINTS[i][1], half_width=WINDOW)
        assert lam == pytest.approx(case.fit.mass, rel=1e-8), (name, i)
        assert b == pytest.approx(case.fit.damping, rel=1e-8), (name, i)
        # planted difference: the same fit without the 5th-order low-pass
        lam_raw, _ = st.fit_eq_3_24(case.records, point=POINTS[i][1], half_width=WINDOW, lowpass=False)
        assert abs(lam_raw / case.fit.mass - 1.0) > 1e-3, (name, i)


def test_the_order_at_the_second_point_is_the_fits_not_the_implementations(cases):
    """At (0.49, −0.14) the transcription orders Λ_RHI and Λ_PHANToM as rhi's fit does: the order is the data's.

    Their eq. 3.13 values at the plant's configurations differ by less than 0.1 %, below the fit's spread.
    """
    fit = {n: st.fit_eq_3_24(cases[n, 1].records, point=POINTS[1][1], half_width=WINDOW)[0] for n in ("RHI", "PHANToM")}
    assert (fit["RHI"] <= fit["PHANToM"]) is (cases["RHI", 1].fit.mass <= cases["PHANToM", 1].fit.mass)
    assert abs(cases["RHI", 1].lam_model / cases["PHANToM", 1].lam_model - 1.0) < 1e-3
