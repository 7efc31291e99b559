"""What kind of effect is missing: residuals tested against generic signatures.

When ``diagnose`` finds a residual that no candidate effect explains (``unexplained``, or
a residual left after the best candidate), the residuals ``r = measured − model`` are
tested against a few generic shapes, each a small linear model fitted by weighted least
squares. A signature is a *lead*, not a diagnosis: it says which kind of physics would
reproduce the residual's shape, not which mechanism causes it.

**Loop residuals** (``LoopResidual``): per record, both branches of the last loop on a
force grid (``validation.loops.branch_residuals``: each loop centred on the midpoint of its
peaks, a band around F = 0 left out), with σ per point from the record's noise and the
model floor. Signatures, their regressors (coefficients common to every record) and the
nuisance terms fitted with them (``SIGNATURES``):

* ``compliance`` — series compliance: ``r = c·F`` [mm/N];
* ``stiffening`` — stiffening (size < 0) or softening (> 0) beyond a linear compliance:
  ``r = c·F + a·(F/F_ref)|F/F_ref|^k``, k ∈ {1, 2, 3} (the best; its p-value multiplied by 3),
  a in mm at the largest amplitude F_ref;
* ``step`` — a step at F = 0 (free play, backlash) beyond a linear compliance:
  ``r = c·F + b·sign(F)`` [mm];
* ``offset`` — a constant left after centring [mm]: the displacement zero is arbitrary, so
  an offset of the whole record is taken out by the centring; what remains is an
  asymmetry of the loop between tension and compression;
* ``drift`` — ``r = o + v·p`` with p the record's time (or, without ``time_s``, its
  sample index) as a fraction of the last loop: v in mm per loop (creep, thermal drift);
* ``rate`` — a loop that depends on the loading rate, in the better of two forms (its
  p-value multiplied by 2): a viscous element in parallel, ``r = w·β + τ·(−dF/dt)`` (the
  width grows with the rate; τ in mm·s/N), or one in series that creeps,
  ``r = w·β + φ·β(F_max² − F²)/(2|dF/dt|)`` (the displacement it gathers since the branch's
  reversal, ∫F dt on a ramp: the width falls as the rate rises; φ in mm/(N·s)); β = +1 on
  the descending and −1 on the ascending branch (a constant width change, which the
  friction level already covers). Not testable without ``time_s`` or when |dF/dt| varies by
  less than ``RATE_SPREAD``.

**Loss residuals** (``LossResidual``): per design point, ``y = ln(η_measured/η_model)``
with σ from the loop-area σ; ``loss`` — an amplitude-dependent loss: ``y = a_g + s·ln Fg``
with one constant a_g per design value (a level error is the friction's), s the
difference of the log-log slopes of η against Fg (measured minus model).

**Significance** (as in ``validation.diagnose``): ``F = (Δχ²/q) / max(1, χ²₁/(n − p))``
(Δχ² the fall of χ² from the nuisance model to the full one, q the signature's terms;
residuals larger than their σ inflate the scale) against F(q, n − p), at α/m
(Bonferroni over the m signatures tested). A significant signature **fits** when its full
model leaves χ² within the noise (χ²₁ ≤ the χ²_{n−p} quantile 1 − α); otherwise it fits
**partly**, and the table says which fraction of the excess χ² over n it explains. When none fits
alone, the significant signatures are also fitted together (``together``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
from scipy import stats

FloatArray = npt.NDArray[np.float64]

RATE_SPREAD = 0.1
"""Least relative spread (std/mean) of |dF/dt| over the loop points for a rate test."""

RATE_FORMS = (
    "in parallel: width ∝ dF/dt",
    "in series (creep): width ∝ ∫F dt, falling with the rate",
)
"""The two viscous forms the rate signature tries."""

RATE_UNITS = ("mm·s/N", "mm/(N·s)")
"""The unit of the rate signature's size in each form: τ, or the fluidity φ."""

STIFFENING_POWERS = (1.0, 2.0, 3.0)
"""Powers k tried for the stiffening signature F|F|^k."""

GUIDE = "docs/user_effects.md"
"""How to write an effect of a kind (a user's file next to MODEL.toml)."""

SIGNATURES = {
    "compliance": ("series compliance (δ ∝ F)", "mm/N", "a post effect δ += c·F"),
    "stiffening": (
        "stiffening (<0) or softening (>0), δ ∝ F|F|^k, at the largest Fg",
        "mm",
        "a post effect δ += a·F|F|^k",
    ),
    "step": ("a step at F = 0 (free play, backlash)", "mm", "a post effect δ += b·sign(F)"),
    "offset": ("a constant left after centring (tension/compression asymmetry)", "mm", ""),
    "drift": (
        "drift over the loop (creep, thermal)",
        "mm/loop",
        "a time-aware post effect δ += v·t",
    ),
    "rate": (
        "loop width changing with the loading rate (viscous, in parallel or in series)",
        "mm·s/N",
        "a time-aware post effect δ −= τ·dF/dt (as studies/examples/effects/damper.py)",
    ),
    "loss": (
        "amplitude-dependent loss (log-log slope of η against Fg)",
        "—",
        "an effect whose dissipation grows with Fg",
    ),
}
"""Signature kind → (what it is in words, unit of its size, the kind of effect to write)."""

LOSS_SIGNATURES = ("loss",)
"""The signatures tested on the loss residuals (the others on the loop residuals)."""


@dataclass(frozen=True)
class LoopResidual:
    """One record's branch residuals, measured − model, on a force grid.

    Attributes:
        case_id: The record.
        force_n: Grid force of each point, shape (n,) [N].
        branch: +1 on the descending, −1 on the ascending branch, shape (n,).
        residual_mm: δ_measured − δ_model, shape (n,) [mm].
        sigma_mm: σ of each residual, shape (n,) [mm].
        progress: Time (or sample index) of each point as a fraction of the last loop,
            shape (n,) [-].
        rate_n_per_s: dF/dt of the record at each point, shape (n,) [N/s], or None
            (no ``time_s``).
    """

    case_id: str
    force_n: FloatArray
    branch: FloatArray
    residual_mm: FloatArray
    sigma_mm: FloatArray
    progress: FloatArray
    rate_n_per_s: FloatArray | None = None


@dataclass(frozen=True)
class LossResidual:
    """Loss-factor residuals per design point.

    Attributes:
        amplitude_n: Fg of each point, shape (n,) [N].
        group: The design value of each point (one constant per value), shape (n,).
        log_ratio: ln(η_measured/η_model), shape (n,).
        sigma: σ of ``log_ratio``, shape (n,).
    """

    amplitude_n: FloatArray
    group: FloatArray
    log_ratio: FloatArray
    sigma: FloatArray


@dataclass(frozen=True)
class Signature:
    """One signature's test.

    Attributes:
        kind: A key of ``SIGNATURES``.
        size: The fitted size (unit ``SIGNATURES[kind][1]``), NaN when not testable.
        size_sigma: Its standard error (scaled like the F statistic).
        p_value: p of the F test (Bonferroni factor not applied), NaN when not testable.
        significant: p < α/m.
        explained: Fraction of the excess χ² its full model explains.
        fits: Significant, and its full model leaves χ² within the noise.
        note: Why it is not testable, or a detail (the power k), "" otherwise.
    """

    kind: str
    size: float
    size_sigma: float
    p_value: float
    significant: bool
    explained: float
    fits: bool
    note: str = ""

    @property
    def testable(self) -> bool:
        """Whether the signature could be tested at all."""
        return math.isfinite(self.p_value)

    @property
    def word(self) -> str:
        """``fits``, ``fits partly``, ``does not fit`` or ``not testable: …``."""
        if not self.testable:
            return f"not testable: {self.note}"
        if self.fits:
            return "fits"
        return "fits partly" if self.significant else "does not fit"

    @property
    def unit(self) -> str:
        """The unit of ``size``: the rate row's depends on the form that fitted best."""
        if self.note in RATE_FORMS:  # only the rate row names a form
            return RATE_UNITS[RATE_FORMS.index(self.note)]
        return SIGNATURES[self.kind][1]

    def to_dict(self) -> dict[str, Any]:
        """Return a JSON-ready dict."""
        return {
            "kind": self.kind,
            "what": SIGNATURES[self.kind][0],
            "size": self.size if self.testable else None,
            "size_sigma": self.size_sigma if self.testable else None,
            "unit": self.unit,
            "p_value": self.p_value if self.testable else None,
            "significant": self.significant,
            "explained": self.explained if self.testable else None,
            "fits": self.fits,
            "word": self.word,
            "note": self.note,
            "write": SIGNATURES[self.kind][2],
        }


@dataclass(frozen=True)
class SignatureTable:
    """The signatures tested on one residual set.

    Attributes:
        rows: One per signature kind, in ``SIGNATURES`` order.
        alpha: The family's false-alarm probability.
        n_tested: m, the signatures tested (the Bonferroni factor).
        together: The significant signatures fitted together: (kinds, explained
            fraction, fits), or None when fewer than two are significant or one fits.
        residual_of: Which model's residual was tested, in words.
    """

    rows: tuple[Signature, ...]
    alpha: float
    n_tested: int
    together: tuple[tuple[str, ...], float, bool] | None = None
    residual_of: str = "the model"

    @property
    def fitting(self) -> tuple[str, ...]:
        """The kinds that fit."""
        return tuple(r.kind for r in self.rows if r.fits)

    def summary(self) -> str:
        """Which kinds fit and which do not, in words, with the honest caveat."""
        ranked = sorted(self.rows, key=lambda r: -r.explained)
        fit = [r.kind for r in ranked if r.fits]
        part = [f"{r.kind} ({r.explained:.0%})" for r in ranked if r.significant and not r.fits]
        if fit:
            s = f"the residuals have the shape of: {', '.join(fit)}"
        elif part:
            s = f"no single signature fits; partly (share of the excess χ²): {', '.join(part)}"
        else:
            s = "no generic signature fits the residuals at this α"
        if self.together is not None:
            kinds, explained, ok = self.together
            s += f"; {' + '.join(kinds)} together explain {explained:.0%} of the excess χ²" + (
                " (within the noise)" if ok else ""
            )
        return (
            f"{s}. A signature is a lead, not a diagnosis: it names the shape of the "
            f"residual, not its cause. How to write an effect of that kind: {GUIDE}"
        )

    def text(self) -> str:
        """Return the table as lines of text."""
        lines = [
            f"signatures of the residual (measured − {self.residual_of}), α = {self.alpha:g} "
            f"over {self.n_tested} tested:"
        ]
        for r in self.rows:
            unit = r.unit
            if not r.testable:
                lines.append(f"  {r.kind:<11} {r.word}")
                continue
            note = f" ({r.note})" if r.note else ""
            share = f", explains {r.explained:.0%}" if r.significant else ""
            lines.append(
                f"  {r.kind:<11} {r.size:+.3g} ± {r.size_sigma:.2g} {unit}{note}: "
                f"p {r.p_value:.2g}{share} — {r.word}"
            )
        lines.append(self.summary())
        return "\n".join(lines)

    def to_dict(self) -> dict[str, Any]:
        """Return a JSON-ready dict."""
        together = None
        if self.together is not None:
            kinds, explained, ok = self.together
            together = {"kinds": list(kinds), "explained": explained, "fits": ok}
        return {
            "alpha": self.alpha,
            "residual_of": self.residual_of,
            "n_tested": self.n_tested,
            "rows": [r.to_dict() for r in self.rows],
            "fitting": list(self.fitting),
            "together": together,
            "summary": self.summary(),
            "guide": GUIDE,
        }


@dataclass(frozen=True)
class _Fit:
    beta: FloatArray
    cov: FloatArray
    chi2: float
    dof: int


def _wls(y: FloatArray, s: FloatArray, X: FloatArray) -> _Fit:
    """Weighted least squares of y on the columns of X (shape (n, p)), σ = s."""
    A = X / s[:, None]
    b = y / s
    n, p = A.shape
    if p == 0:
        return _Fit(np.zeros(0), np.zeros((0, 0)), float(b @ b), n)
    beta, _, rank, _ = np.linalg.lstsq(A, b, rcond=None)
    res = b - A @ beta
    cov = np.linalg.pinv(A.T @ A)
    return _Fit(
        np.asarray(beta, dtype=np.float64),
        np.asarray(cov, dtype=np.float64),
        float(res @ res),
        n - int(rank),
    )


class _Test:
    """Fits a residual set's signatures: nested F tests against its nuisance terms."""

    def __init__(self, y: FloatArray, s: FloatArray) -> None:
        self.y, self.s = y, s
        self.chi2_zero = float(np.sum((y / s) ** 2))
        self.n = len(y)

    def explained(self, chi2: float) -> float:
        """Fraction of the excess χ² over n that a fit to ``chi2`` removes, in [0, 1] (0: none)."""
        excess = self.chi2_zero - self.n
        if excess <= 0.0:
            return 0.0
        return min(max((self.chi2_zero - chi2) / excess, 0.0), 1.0)

    def run(
        self, nuisance: FloatArray, terms: FloatArray, alpha: float
    ) -> tuple[float, float, float, float, bool, FloatArray]:
        """(size, σ, p, explained, within noise, full design) of the last column of ``terms``."""
        full = np.column_stack([nuisance, terms])
        if np.linalg.matrix_rank(full / self.s[:, None]) < full.shape[1] or self.n <= full.shape[1]:
            return math.nan, math.nan, math.nan, 0.0, False, full
        f0, f1 = _wls(self.y, self.s, nuisance), _wls(self.y, self.s, full)
        q = terms.shape[1]
        inflate = max(1.0, f1.chi2 / f1.dof)
        F = max(f0.chi2 - f1.chi2, 0.0) / q / inflate
        p = float(stats.f.sf(F, q, f1.dof))
        explained = self.explained(f1.chi2)
        within = f1.chi2 <= float(stats.chi2.ppf(1.0 - alpha, f1.dof))
        size = float(f1.beta[-1])
        sigma = math.sqrt(max(float(f1.cov[-1, -1]), 0.0) * inflate)
        return size, sigma, p, explained, within, full

    def together(self, designs: Sequence[FloatArray], alpha: float) -> tuple[float, bool]:
        """(explained, within noise) of the union of ``designs``' columns."""
        f = _wls(self.y, self.s, np.column_stack(designs))  # shared columns: rank counts once
        return self.explained(f.chi2), f.chi2 <= float(stats.chi2.ppf(1.0 - alpha, max(f.dof, 1)))


def _loop_designs(loops: Sequence[LoopResidual]) -> dict[str, Any]:
    """Per signature: (nuisance columns, candidate term sets, note) on the stacked loop points."""
    F = np.concatenate([lr.force_n for lr in loops])
    beta = np.concatenate([lr.branch for lr in loops])
    prog = np.concatenate([lr.progress for lr in loops])
    x = F / float(np.max(np.abs(F)))  # F/F_ref: the stiffening's size is δ at F_ref
    one = np.ones((len(F), 1))
    lin = F[:, None]
    none = np.zeros((len(F), 0))
    out: dict[str, Any] = {
        "compliance": (none, [lin], ""),
        "stiffening": (
            lin,
            [(x * np.abs(x) ** k)[:, None] for k in STIFFENING_POWERS],
            "k",
        ),
        "step": (lin, [np.sign(F)[:, None]], ""),
        "offset": (none, [one], ""),
        "drift": (one, [prog[:, None]], ""),
    }
    rates = [lr.rate_n_per_s for lr in loops]
    if any(r is None for r in rates):
        out["rate"] = "no time_s in the records"
    else:
        rate = np.concatenate([np.asarray(r) for r in rates])
        a = np.abs(rate)
        if not np.all(np.isfinite(rate)) or np.std(a) < RATE_SPREAD * np.mean(a):
            out["rate"] = f"one loading rate (|dF/dt| varies by < {RATE_SPREAD:.0%})"
        else:
            # the record's own peak force (each record's grid spans its ±Fg)
            fmax = np.concatenate(
                [np.full(len(lr.force_n), np.max(np.abs(lr.force_n))) for lr in loops]
            )
            creep = beta * (fmax**2 - F**2) / (2.0 * a)  # ∫F dt since the branch's reversal
            out["rate"] = (beta[:, None], [-rate[:, None], creep[:, None]], "rate")
    return out


def loop_signatures(
    loops: Sequence[LoopResidual],
    loss: LossResidual | None,
    alpha: float,
    residual_of: str = "the model",
) -> SignatureTable:
    """Test the loop and loss residuals against every signature (module docstring).

    Args:
        loops: Branch residuals of the records (may be empty: η-only data).
        loss: Loss-factor residuals, or None.
        alpha: False-alarm probability of the whole table.
        residual_of: Which model's residual it is, in words.
    """
    plans: dict[str, Any] = {k: "no loop records" for k in SIGNATURES if k not in LOSS_SIGNATURES}
    loop_test = None
    if loops:
        y = np.concatenate([lr.residual_mm for lr in loops])
        s = np.concatenate([lr.sigma_mm for lr in loops])
        loop_test = _Test(y, s)
        plans = _loop_designs(loops)
    plans["loss"] = _loss_plan(loss)
    loss_test = None if loss is None else _Test(loss.log_ratio, loss.sigma)
    m = sum(1 for p in plans.values() if not isinstance(p, str))
    raw: dict[str, Any] = {}
    for kind, plan in plans.items():
        if isinstance(plan, str):
            raw[kind] = None
            continue
        test = loss_test if kind in LOSS_SIGNATURES else loop_test
        assert test is not None
        nuisance, options, note = plan
        tried = [(j, test.run(nuisance, terms, alpha)) for j, terms in enumerate(options)]
        finite = [t for t in tried if math.isfinite(t[1][2])] or tried
        j, (size, sigma, p, explained, within, full) = max(finite, key=lambda t: t[1][3])
        if len(options) > 1:
            p = min(1.0, p * len(options))
            note = RATE_FORMS[j] if note == "rate" else f"k = {STIFFENING_POWERS[j]:g}"
        raw[kind] = (size, sigma, p, explained, within, full, note, test)
    level = alpha / max(m, 1)
    rows = []
    for kind in SIGNATURES:
        r = raw[kind]
        if r is None:
            rows.append(
                Signature(kind, math.nan, math.nan, math.nan, False, 0.0, False, plans[kind])
            )
            continue
        size, sigma, p, explained, within, _, note, _ = r
        sig = bool(math.isfinite(p) and p < level)
        fits = sig and within
        if not math.isfinite(p):
            note = note or "its terms are not independent on these points"
        rows.append(Signature(kind, size, sigma, p, sig, explained, fits, note))
    together = None
    sig_loop = [row.kind for row in rows if row.significant and row.kind not in LOSS_SIGNATURES]
    if loop_test is not None and len(sig_loop) >= 2 and not any(r.fits for r in rows):
        explained, ok = loop_test.together([raw[k][5] for k in sig_loop], alpha)
        together = (tuple(sig_loop), explained, ok)
    return SignatureTable(tuple(rows), alpha, m, together, residual_of)


def _loss_plan(loss: LossResidual | None) -> Any:
    """The loss signature's (nuisance, terms, note), or why it is not testable."""
    if loss is None or len(loss.amplitude_n) == 0:
        return "no loss factors"
    groups = np.unique(loss.group)
    nuisance = np.column_stack([(loss.group == g).astype(float) for g in groups])
    multi = [g for g in groups if len(np.unique(loss.amplitude_n[loss.group == g])) >= 2]
    if not multi or len(loss.amplitude_n) < len(groups) + 2:
        return "fewer than 2 amplitudes at a design value, or too few points"
    return nuisance, [np.log(loss.amplitude_n)[:, None]], ""
