"""System identification of the apparent mass and viscous friction along a direction.

The end-effector of a haptic interface pushed by a constant external force along
a direction ``u`` is modelled as the scalar system

    M_x ẍ + Φ ẋ (+ c) = F_ext                      (thesis eqs. 3.24 and 6.22)

with ``x`` the position along ``u`` [m], ``M_x`` the effective apparent inertia
[kg] (Λ of eq. 3.13 in chapter 3), ``Φ`` the viscous (back-drive) friction
[N s/m] and ``c`` an optional constant force [N] (force-sensor bias, or the
Coulomb friction of a motion in one direction). The thesis's procedure (§3.5,
§6.4): velocity and acceleration from the measured position by a second-order
differentiating filter, every signal through a zero-phase 5th-order Butterworth
low-pass, then linear least squares over ten pooled trials.

Why filtering does not bias the fit: the zero-phase filter (``sosfiltfilt`` with
odd padding) is a *linear* operator on a record, and the same operator is applied
to the regressand ``F`` and to the regressors ``ẍ``, ``ẋ`` and the constant, so
an exact relation ``F = M ẍ + Φ ẋ + c`` before filtering holds exactly after it.
What can break it is the differentiator at a record's ends, where its fits are
one-sided: those samples are dropped before filtering and a further derivative
window is trimmed after it (`regressors`, `identify`). The cut-off then trades
noise against nothing in the model; it need only stay above the dynamics.

Default cut-off, 20 Hz: the free response has a single pole at ``Φ/(2π M)``,
0.4-1.3 Hz for the devices of Tables 3.2 and 6.1 (``M`` 0.04-0.57 kg, ``Φ``
0.3-0.6 N s/m), and voluntary hand motion stays below ~10 Hz; 20 Hz keeps both
with margin while removing encoder and force-sensor noise, whose second
derivative grows as ``f²``. Raise it for short records of a light device.

Uncertainty: filtered, densely sampled residuals are strongly autocorrelated, so
ordinary least-squares standard errors would be far too small. The default
(``covariance="auto"``) uses cluster-robust standard errors with one cluster per
trial (independent trials, arbitrary correlation within a trial; Student t with
``n_trials − 1`` degrees of freedom) when there are at least 5 trials, and
Newey-West (HAC) standard errors with a lag of two cut-off periods otherwise.
Trials must have independent noise for the cluster errors to hold.

Measured on simulated trials (`simulate_record`: ten trials of 0.12-0.3 s at
1 kHz under 0.5-1.5 N; M 0.036-0.5 kg, Φ 0.3-2 N s/m): noiseless relative error
below 2·10⁻⁴; with 10 µm position and 0.02 N force noise the 95 % intervals
covered the truth in 92-99 % of 100 data sets per plant, with 50 µm and 0.05 N
in 89-95 % for M <= 0.125 kg. Position noise also enters the regressors (errors
in variables) and biases ``M_x`` towards zero: with 50 µm on the 0.5 kg device
(acceleration only ~2 m/s²) the bias was -2 % against a standard error of 1.3 %
(coverage 80-85 %); lower the cut-off for heavy, slow devices.
"""

from rhi.analysis.sysid.fit import SysidResult, identify, regressors
from rhi.analysis.sysid.records import Record, from_csv, project, simulate_record
from rhi.analysis.sysid.signals import (
           MIN_SAMPLES,
           UNIFORM_TOLERANCE,
           default_window,
           derivatives,
           lowpass,
)

__all__ = ["MIN_SAMPLES", "UNIFORM_TOLERANCE", "Record", "SysidResult", "default_window", "derivatives", "from_csv",
           "identify", "lowpass", "project", "regressors", "simulate_record"]
