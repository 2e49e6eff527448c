"""Group comparisons of the thesis's user studies: ANOVA and adjusted paired t-tests.

What the thesis does:

- §3.6 (stiffness discrimination, 10 subjects × 3 devices): a one-way ANOVA on
  the WF, reported as F(2, 27) = 7.36. The degrees of freedom (27 = 30 − 3)
  are those of the *between-subjects* one-way ANOVA (`one_way_anova`,
  ``scipy.stats.f_oneway``), although every subject used every device; the
  repeated-measures ANOVA that this design calls for (F(2, 18)) is
  `repeated_measures_anova` (``statsmodels`` ``AnovaRM``). Then paired-sample
  t-tests between the devices, p-values adjusted by Holm-Bonferroni
  (`paired_t_tests` with ``correction="holm"``).
- §5.4, Table 5.2: paired t-tests of one-sided hypotheses ("Scenario 1 <
  Scenario 2"), p-values adjusted for the false discovery rate
  (Benjamini-Hochberg; ``correction="fdr_bh"``, ``alternative="less"``).

Everything returns dataclasses; nothing prints.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from collections.abc import Mapping, Sequence

import numpy as np
from numpy.typing import ArrayLike

from rhi._validate import float_array, scalar
from rhi.errors import InvalidInput

_CORRECTIONS = ("holm", "fdr_bh", "bonferroni", "none")
_ALTERNATIVES = ("two-sided", "less", "greater")


@dataclasses.dataclass(frozen=True)
class Summary:
    """Descriptive statistics of one group (Tables 3.3 and 5.1: "mean (std)").

    Attributes:
        name: group name.
        n: number of observations.
        mean: sample mean.
        std: sample standard deviation (ddof = 1).
        median: sample median (Fig. 3.10's red line).
    """

    name: str
    n: int
    mean: float
    std: float
    median: float


@dataclasses.dataclass(frozen=True)
class AnovaResult:
    """Result of an ANOVA across groups.

    Attributes:
        statistic: F.
        p_value: P(F' >= F) under the null hypothesis of equal means.
        df_between: numerator degrees of freedom (groups − 1).
        df_within: denominator degrees of freedom.
        method: "one-way" or "repeated-measures".
        groups: group names in order.
    """

    statistic: float
    p_value: float
    df_between: float
    df_within: float
    method: str
    groups: tuple[str, ...]

    def __str__(self) -> str:
        return f"F({self.df_between:g}, {self.df_within:g}) = {self.statistic:.2f}, p = {self.p_value:.3g}"


@dataclasses.dataclass(frozen=True)
class PairedTest:
    """One paired-sample t-test between groups ``a`` and ``b`` (differences a − b).

    Attributes:
        a, b: group names; the hypothesis reads "a < b" for ``alternative="less"``.
        statistic: t.
        df: degrees of freedom (n − 1).
        p_value: unadjusted p-value.
        p_adjusted: p-value adjusted over the family of tests (``correction``).
        significant: ``p_adjusted <= alpha`` (as ``multipletests`` decides).
        mean_difference: mean of a − b.
        alternative: "two-sided", "less" or "greater".
        correction: "holm", "fdr_bh", "bonferroni" or "none".
        alpha: family-wise error rate or false discovery rate.
    """

    a: str
    b: str
    statistic: float
    df: int
    p_value: float
    p_adjusted: float
    significant: bool
    mean_difference: float
    alternative: str
    correction: str
    alpha: float

    @property
    def hypothesis(self) -> str:
        """The alternative hypothesis in Table 5.2's wording, e.g. "RHI < Rehab"."""
        op = {"two-sided": "≠", "less": "<", "greater": ">"}[self.alternative]
        return f"{self.a} {op} {self.b}"


def _groups(
    name: str, groups: Mapping[str, ArrayLike], *, paired: bool, min_n: int = 2, min_groups: int = 2
) -> dict[str, np.ndarray]:
    if not isinstance(groups, Mapping):
        raise InvalidInput(f"{name}: expected a mapping of group name -> observations, got {type(groups).__name__}")
    if len(groups) < min_groups:
        raise InvalidInput(f"{name}: need at least {min_groups} group(s), got {len(groups)}")
    out = {}
    for g, values in groups.items():
        a = float_array(f"{name}[{g!r}]", values)
        if a.ndim != 1:
            raise InvalidInput(f"{name}[{g!r}]: expected a 1-D array, got shape {a.shape}")
        if a.size < min_n:
            raise InvalidInput(f"{name}[{g!r}]: {a.size} observations; need at least {min_n}")
        if not np.isfinite(a).all():
            i = int(np.flatnonzero(~np.isfinite(a))[0])
            raise InvalidInput(f"{name}[{g!r}]: non-finite value at index {i}")
        out[str(g)] = a
    if paired:
        sizes = {g: a.size for g, a in out.items()}
        if len(set(sizes.values())) != 1:
            raise InvalidInput(f"{name}: paired data need the same subjects in every group, got sizes {sizes}")
    return out


def describe(groups: Mapping[str, ArrayLike]) -> list[Summary]:
    """Mean, standard deviation (ddof = 1) and median of every group (Tables 3.3, 5.1).

    Args:
        groups: ``{name: (n,) observations}``.

    Returns:
        list of `Summary` in the mapping's order.
    """
    data = _groups("groups", groups, paired=False, min_n=2, min_groups=1)
    return [
        Summary(name=g, n=int(a.size), mean=float(a.mean()), std=float(a.std(ddof=1)), median=float(np.median(a)))
        for g, a in data.items()
    ]


def one_way_anova(groups: Mapping[str, ArrayLike]) -> AnovaResult:
    """Between-subjects one-way ANOVA (``scipy.stats.f_oneway``), as reported in §3.6 and §5.4.

    Args:
        groups: ``{name: (n_g,) observations}``, at least two groups of two.

    Returns:
        `AnovaResult` with df = (k − 1, N − k).
    """
    from scipy import stats

    data = _groups("groups", groups, paired=False)
    within = sum(float(((a - a.mean()) ** 2).sum()) for a in data.values())
    scale = max(float(np.abs(a).max()) for a in data.values())
    if within <= (1e-12 * max(scale, 1e-300)) ** 2:
        raise InvalidInput("groups: no variance within any group (constant data); F is undefined")
    res = stats.f_oneway(*data.values())
    n = sum(a.size for a in data.values())
    k = len(data)
    return AnovaResult(float(res.statistic), float(res.pvalue), float(k - 1), float(n - k), "one-way", tuple(data))


def one_way_anova_from_summary(
    means: Sequence[float], stds: Sequence[float], ns: Sequence[int], *, names: Sequence[str] | None = None
) -> AnovaResult:
    """One-way ANOVA from group means, standard deviations (ddof = 1) and sizes.

    Lets a published "mean (std)" table be checked against its reported F, e.g.
    Table 3.3 against F(2, 27) = 7.36; agrees with `one_way_anova` on raw data.

    Args:
        means: (k,) per-group mean.
        stds: (k,) per-group sample s.d.
        ns: (k,) per-group size (>= 2).
        names: group names (default "g0", "g1", ...).

    Returns:
        `AnovaResult` (method "one-way").
    """
    from scipy import stats

    m = np.asarray(means, dtype=float)
    s = np.asarray(stds, dtype=float)
    n = np.asarray(ns, dtype=float)
    if not (m.ndim == s.ndim == n.ndim == 1 and m.shape == s.shape == n.shape and m.size >= 2):
        raise InvalidInput(
            f"means/stds/ns: expected equal 1-D shapes with >= 2 groups, got {m.shape}, {s.shape}, {n.shape}"
        )
    if not (np.isfinite(m).all() and np.isfinite(s).all() and (s >= 0).all()):
        raise InvalidInput("means/stds: need finite means and non-negative standard deviations")
    if not ((n >= 2).all() and np.all(n == np.round(n))):
        raise InvalidInput(f"ns: need integer group sizes >= 2, got {ns!r}")
    k, total = m.size, n.sum()
    grand = (n * m).sum() / total
    ss_between = (n * (m - grand) ** 2).sum()
    ss_within = ((n - 1) * s**2).sum()
    df_b, df_w = k - 1, total - k
    if ss_within == 0:
        raise InvalidInput("stds: all zero; F is undefined")
    F = (ss_between / df_b) / (ss_within / df_w)
    labels = tuple(names) if names is not None else tuple(f"g{i}" for i in range(k))
    if len(labels) != k:
        raise InvalidInput(f"names: expected {k} names, got {len(labels)}")
    return AnovaResult(float(F), float(stats.f.sf(F, df_b, df_w)), float(df_b), float(df_w), "one-way", labels)


def repeated_measures_anova(groups: Mapping[str, ArrayLike]) -> AnovaResult:
    """One-way repeated-measures ANOVA (``statsmodels.stats.anova.AnovaRM``).

    The design of §3.6 (every subject on every device); the thesis reports the
    between-subjects `one_way_anova` instead.

    Args:
        groups: ``{condition: (n_subjects,) observations}``, aligned by subject.

    Returns:
        `AnovaResult` with df = (k − 1, (k − 1)(n − 1)), method "repeated-measures".
    """
    import pandas as pd
    from statsmodels.stats.anova import AnovaRM

    data = _groups("groups", groups, paired=True)
    X = np.column_stack(list(data.values()))  # (subjects, conditions)
    resid = X - X.mean(axis=0) - X.mean(axis=1, keepdims=True) + X.mean()
    if float((resid**2).sum()) <= (1e-12 * max(float(np.abs(X).max()), 1e-300)) ** 2 * X.size:
        raise InvalidInput("groups: no residual variance (constant data, or every subject differs by a constant "
                           "offset); the repeated-measures F is undefined")
    n = next(iter(data.values())).size
    frame = pd.DataFrame(
        {
            "subject": np.tile(np.arange(n), len(data)),
            "condition": np.repeat(list(data), n),
            "value": np.concatenate(list(data.values())),
        }
    )
    table = AnovaRM(frame, depvar="value", subject="subject", within=["condition"]).fit().anova_table
    row = table.loc["condition"]
    return AnovaResult(
        float(row["F Value"]),
        float(row["Pr > F"]),
        float(row["Num DF"]),
        float(row["Den DF"]),
        "repeated-measures",
        tuple(data),
    )


def adjust(p_values: ArrayLike, *, correction: str = "holm", alpha: float = 0.05) -> tuple[np.ndarray, np.ndarray]:
    """Adjust a family of p-values (``statsmodels.stats.multitest.multipletests``).

    Args:
        p_values: (m,) unadjusted p-values in [0, 1].
        correction: "holm" (Holm-Bonferroni, §3.6), "fdr_bh" (Benjamini-Hochberg FDR,
            Table 5.2), "bonferroni" or "none".
        alpha: family-wise error rate (or FDR).

    Returns:
        ``(p_adjusted, reject)``: (m,) adjusted p-values and (m,) booleans.
    """
    p = float_array("p_values", p_values)
    if p.ndim != 1 or p.size == 0 or not np.all((p >= 0) & (p <= 1)):
        raise InvalidInput(f"p_values: expected a non-empty 1-D array in [0, 1], got {p_values!r}")
    if correction not in _CORRECTIONS:
        raise InvalidInput(f"correction: expected one of {_CORRECTIONS}, got {correction!r}")
    if not (0 < scalar("alpha", alpha) < 1):
        raise InvalidInput(f"alpha: must lie in (0, 1), got {alpha!r}")
    if correction == "none":
        return p.copy(), p <= alpha
    from statsmodels.stats.multitest import multipletests

    reject, p_adj, _, _ = multipletests(p, alpha=alpha, method=correction)
    return np.asarray(p_adj, dtype=float), np.asarray(reject, dtype=bool)


def paired_t_tests(
    groups: Mapping[str, ArrayLike],
    *,
    pairs: Sequence[tuple[str, str]] | None = None,
    alternative: str = "two-sided",
    correction: str = "holm",
    alpha: float = 0.05,
) -> list[PairedTest]:
    """Paired-sample t-tests between groups with adjusted p-values (§3.6: Holm; Table 5.2: FDR).

    Args:
        groups: ``{name: (n,) observations}``, aligned by subject.
        pairs: ``(a, b)`` pairs to test (difference a − b); default every pair
            ``(g_i, g_j)``, i < j, in the mapping's order.
        alternative: "two-sided", "less" (a < b, Table 5.2's hypotheses) or "greater".
        correction: "holm", "fdr_bh", "bonferroni" or "none" (see `adjust`).
        alpha: family-wise error rate (or FDR) for ``significant``.

    Returns:
        list of `PairedTest`, one per pair, in the order of ``pairs``.

    Raises:
        InvalidInput: fewer than two groups, unequal group sizes, unknown group
            names, unknown alternative or correction.
    """
    from scipy import stats

    data = _groups("groups", groups, paired=True)
    if alternative not in _ALTERNATIVES:
        raise InvalidInput(f"alternative: expected one of {_ALTERNATIVES}, got {alternative!r}")
    if correction not in _CORRECTIONS:
        raise InvalidInput(f"correction: expected one of {_CORRECTIONS}, got {correction!r}")
    todo = list(itertools.combinations(data, 2)) if pairs is None else [(str(a), str(b)) for a, b in pairs]
    if not todo:
        raise InvalidInput("pairs: empty")
    for a, b in todo:
        for g in (a, b):
            if g not in data:
                raise InvalidInput(f"pairs: unknown group {g!r} (groups: {list(data)})")
        if a == b:
            raise InvalidInput(f"pairs: a group compared with itself ({a!r})")
    raw = []
    for a, b in todo:
        d = data[a] - data[b]
        if np.all(d == d[0]):
            raise InvalidInput(f"groups: the differences {a!r} − {b!r} are constant; t is undefined")
        res = stats.ttest_rel(data[a], data[b], alternative=alternative)
        raw.append((float(res.statistic), float(res.pvalue), float(d.mean())))
    p_adj, reject = adjust([r[1] for r in raw], correction=correction, alpha=alpha)
    n = next(iter(data.values())).size
    return [
        PairedTest(
            a=a,
            b=b,
            statistic=t,
            df=n - 1,
            p_value=p,
            p_adjusted=float(pa),
            significant=bool(rej),
            mean_difference=md,
            alternative=alternative,
            correction=correction,
            alpha=float(alpha),
        )
        for (a, b), (t, p, md), pa, rej in zip(todo, raw, p_adj, reject)
    ]


def f_p_value(statistic: float, df_between: float, df_within: float) -> float:
    """p-value of an F statistic, to check a reported "F(d1, d2) = F, p = ..." pair.

    E.g. §3.6 reports F(2, 27) = 7.36 with P = 0.0032; ``f_p_value(7.36, 2, 27)`` is 0.0028.
    """
    from scipy import stats

    if not (math.isfinite(statistic) and statistic >= 0 and df_between > 0 and df_within > 0):
        raise InvalidInput(
            "statistic/df: need F >= 0 and positive degrees of freedom, "
            f"got {statistic!r}, {df_between!r}, {df_within!r}"
        )
    return float(stats.f.sf(statistic, df_between, df_within))
