"""How the curvature is fitted: the one place that chooses the fit's form, kernel, anchors and carry.

The kernel choice (:mod:`heatcurv.choice.scale`) measures the noise and picks a
kernel width per region; the options may fix the width (``scale=``), the
ball (``radius=``) or ask for the paper's tensor fit. :func:`plan_fit` turns
these into a :class:`FitPlan`; the estimator runs what the plan says, and
every label a result carries (``info["scale"].fit``, the command line's
kernel, a tiled run's report) is the plan's.

=======================  =======================================================================
path                     when
=======================  =======================================================================
paper's tensor fit       ``fit="constrained"`` (eq 3.1, the paper's method) or ``"unconstrained"``:
                         over the operator's balls, at every point
chord fit at each point  a clean cloud (the noise gate of :func:`heatcurv.choice.scale.select_scale`) and
                         a kernel of at most ``k_fit`` neighbours
one ball radius          ``radius=``: the chord or the denoised form (the noise gate) over that
                         ball, at every point
anchored denoised fit    noise, or a kernel wider than ``k_fit``: the denoised form fitted at
                         anchors (:mod:`heatcurv.fits.anchors`) and carried to every point
with anchor normals      noise above ``TUNING.strong_noise`` spacings: the anchors find and orient
                         their own normals (the operator's balls are swamped)
with very low noise      the very-low-noise band (:attr:`heatcurv.choice.scale.ScaleChoice.low_noise`):
                         the quartic refit, denser anchors and the cubic regression of their tensors
with standard errors     the chord fit's own kernel (not ``radius=``) on a whole cloud, unless ``se=False``:
                         refits at ``k`` and ``2 k`` at sample centres (:mod:`heatcurv.fits.uncertainty`)
=======================  =======================================================================
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..fits.anchors import anchors_per_ball, carry_degree
from ..tuning import TUNING

__all__ = ["FORMS", "FitPlan", "flattening", "noise_swamps_balls", "noisy_residuals", "plan_fit"]

#: The fit forms a plan names: the chord fit, its denoised form (:mod:`heatcurv.fits.chordfit`) and the paper's
#: tensor fit with or without its constraint (:mod:`heatcurv.fits.principal`).
FORMS = ("chord", "denoised", "paper-constrained", "paper-free")


@dataclass(frozen=True)
class FitPlan:
    """What the curvature fit of one cloud runs (``result.info["plan"]``).

    Attributes
    ----------
    form : str
        One of :data:`FORMS`.
    k : int
        Neighbours in the median point's kernel (0 for the paper's fit and
        with ``radius``: the ball decides).
    k_min, k_max : int
        Narrowest and widest kernel of any point (regions of different noise).
    radius : float or None
        The one ball radius of ``radius=``, input units.
    anchored : bool
        Fitted at anchors and carried to every point; otherwise fitted at every point.
    anchors_per_ball : int
        Anchors in each fitted ball (every point is one where the kernel is narrow;
        :func:`heatcurv.fits.anchors.anchor_rows`); 0 when not anchored.
    anchor_normals : bool
        The anchors start from their own PCA normals, oriented over the anchors.
    refit : bool
        The anchors' low-noise refit (quartic terms, near-pair weights).
    carry_degree : int
        How the anchors' fits reach every point: 0 a weighted mean of the carried
        models, 3 the cubic regression of the anchors' own tensors (very low noise).
    keep_normals : bool
        The caller gave the normals: the fit keeps them.
    wrapped : bool
        Anchored on a cloud whose residual is noise (the kernel choice's ``residual_rise`` at most
        ``TUNING.noise_rise``, the gate of the rays' noise layer too): a point whose anchors' balls are
        round (``TUNING.round_ball``) is not reliable (:attr:`heatcurv.fit_stages.Fitted.wrapped`). Only
        the noise widens a kernel past what the surface allows; on a coarse clean cloud the wide balls
        are round wherever a part is a few spacings across, and that is the cloud's resolution
        (:func:`heatcurv.flags.reliability.resolution`), not a point's flag.
    noisy_misfits : bool
        The kernel choice measured noise, and its quietest centres' residual did not grow with the kernel
        or the noise swamps the operator's balls (:func:`noisy_residuals`): the fit's residual on a
        smooth surface is that noise, nearly the same at every point, and a point whose residual exceeds
        ``TUNING.noise_misfit_factor`` times its
        kernel width's median is a misfit (:func:`heatcurv.flags.reliability.misfits`). Elsewhere the
        residual is the surface's own misfit, which varies from point to point, and the bound is
        ``TUNING.misfit_factor``.
    flattening : bool
        With ``noisy_misfits``, and noise of at least ``TUNING.flattening_noise`` of the spacing: a point
        whose ball radius is under ``1 / TUNING.noise_flattening`` times the noise is not reliable: the
        kernel, which weighs each neighbour by its noisy distance, flattens the fitted heights, and the
        curvature by about ``20 (sigma / R)^2`` (:func:`heatcurv.flags.reliability.flattened`). Under less
        noise the residual a coarse mesh's facets add (CGAL's camel with noise of 0.1 % of its diagonal:
        twice the noise) would make ``sigma`` overstate the flattening.
    standard_errors : bool
        The chord fit's standard errors are computed (:mod:`heatcurv.fits.uncertainty`): with its own
        kernel choice (not ``radius=``), on a whole cloud (not a tile's part) and unless ``se=False``.
    reason : str
        Why this path, in words.
    """

    form: str
    k: int = 0
    k_min: int = 0
    k_max: int = 0
    radius: float | None = None
    anchored: bool = False
    anchors_per_ball: int = 0
    anchor_normals: bool = False
    refit: bool = False
    carry_degree: int = 0
    keep_normals: bool = False
    wrapped: bool = False
    noisy_misfits: bool = False
    flattening: bool = False
    standard_errors: bool = True
    reason: str = ""

    @property
    def denoise(self) -> bool:
        """Whether the fit is the denoised form (an offset and tilt fitted, not the chords' own heights)."""
        return self.form == "denoised"

    @property
    def misfit_factor(self) -> float:
        """The residual, in its kernel width's median residuals, from which a point is a misfit."""
        return TUNING.noise_misfit_factor if self.noisy_misfits else TUNING.misfit_factor

    @property
    def label(self) -> str:
        """``"chord-60"``, ``"denoised-480"``, ``"chord-r0.5"`` or the paper's form."""
        if self.form.startswith("paper"):
            return self.form
        if self.radius is not None:
            return f"{self.form}-r{self.radius:g}"
        return f"{self.form}-{self.k}"

    def describe(self) -> str:
        """The plan in one line (the command line's ``--verbose``)."""
        if self.form.startswith("paper"):
            where = "at every point, on the operator's balls"
        elif not self.anchored:
            where = "at every point"
        else:
            where = f"at anchors ({self.anchors_per_ball} per ball), carried to every point by " + (
                "a weighted mean of their models" if self.carry_degree == 0 else
                f"a degree-{self.carry_degree} regression of their tensors")
        widths = f", {self.k_min}-{self.k_max} neighbours by region" if self.k_min != self.k_max else ""
        extras = [text for flag, text in ((self.refit, "low-noise refit"),
                                          (self.anchor_normals, "anchors orient their own normals"),
                                          (self.wrapped, "round wide balls flagged"),
                                          (self.noisy_misfits, f"misfits from {self.misfit_factor:g}x the noise"),
                                          (self.flattening, f"balls under {1 / TUNING.noise_flattening:.0f}x "
                                                            "the noise flagged"),
                                          (self.keep_normals, "given normals kept")) if flag]
        return (f"{self.label}{widths}, {where}" + "".join(f"; {text}" for text in extras)
                + (f" ({self.reason})" if self.reason else ""))


def plan_fit(options, choice=None, *, keep_normals: bool = False) -> FitPlan:
    """The fit a cloud gets, from the options and the kernel choice.

    Parameters
    ----------
    options : heatcurv.options.Options
        Resolved options (``fit``, ``radius``, ``scale_tuning.k_fit``).
    choice : heatcurv.choice.scale.ScaleChoice, optional
        The kernel choice (:func:`heatcurv.choice.scale.select_scale`, :func:`heatcurv.choice.scale.select_form`
        with ``radius=``, or a tiled run's survey); not used by the paper's fit.
    keep_normals : bool, optional
        The caller gave the normals.

    Returns
    -------
    FitPlan
    """
    if options.fit != "chord":
        form = "paper-constrained" if options.fit == "constrained" else "paper-free"
        return FitPlan(form, keep_normals=keep_normals, standard_errors=False,
                       reason=f"fit={options.fit!r}: the paper's tensor fit, eq 3.1")
    if choice is None:
        raise ValueError("the chord fit's plan needs the kernel choice")
    scale = choice.scale
    widths = np.asarray(choice.k_per_point) if choice.k_per_point is not None else np.array([scale.k])
    k_min, k_max = int(widths.min()), int(widths.max())
    form = "denoised" if scale.denoise else "chord"
    gate = f"noise {choice.relative_noise:.2g} h" if scale.denoise else "clean"
    if options.radius is not None:
        return FitPlan(form, k=scale.k, k_min=k_min, k_max=k_max, radius=float(options.radius),
                       keep_normals=keep_normals, noisy_misfits=noisy_residuals(choice),
                       flattening=flattening(choice), standard_errors=False,
                       reason=f"radius={options.radius:g}; {gate}")
    errors = bool(options.se)
    k_fit = int(options.scale_tuning.k_fit)
    if not scale.denoise and scale.k <= k_fit:
        return FitPlan("chord", k=scale.k, k_min=k_min, k_max=k_max, keep_normals=keep_normals,
                       noisy_misfits=noisy_residuals(choice), flattening=flattening(choice), standard_errors=errors,
                       reason=gate)
    # noise, or a kernel too wide to fit at every point: the denoised form at anchors (its offset
    # absorbs the centre's own height error, which a carried chord fit would keep)
    why = gate if scale.denoise else f"clean, but {scale.k} neighbours is wider than k_fit = {k_fit}"
    low_noise = bool(choice.low_noise)
    if low_noise:
        why += "; very low noise"
    strong = not keep_normals and noise_swamps_balls(choice)
    return FitPlan(
        "denoised", k=scale.k, k_min=k_min, k_max=k_max, anchored=True, anchors_per_ball=anchors_per_ball(low_noise),
        anchor_normals=strong, refit=low_noise, carry_degree=carry_degree(low_noise), keep_normals=keep_normals,
        wrapped=bool(choice.residual_rise <= TUNING.noise_rise), noisy_misfits=noisy_residuals(choice),
        flattening=flattening(choice),
        standard_errors=errors, reason=why,
    )


def noisy_residuals(choice) -> bool:
    """Whether the kernel choice ``choice`` (a :class:`heatcurv.choice.scale.ScaleChoice`; None: no choice) found
    noise, and the residual of the cloud's quietest parts stays that noise as the kernel widens
    (``quiet_rise`` at most ``TUNING.noise_rise``), or the noise swamps the operator's balls
    (:func:`noise_swamps_balls`): a smooth surface's fit residual is then its noise
    (:attr:`FitPlan.noisy_misfits`).

    Where the residual is the surface's own misfit (a coarse mesh's facets, a range map's folds, a scan's
    detail at the kernel's scale) it grows with the kernel even there, and varies from point to point as
    on a clean cloud. So does the residual of noise as thick as a small cloud's balls, whose wide kernels
    also take in the curvature (a sphere of 5000 points with noise of 3 % of its diagonal: ``quiet_rise``
    1.40-1.46); its noise, not misfit, is what swamps the balls (coarse meshes measure at most 0.42 of
    their spacing). NaN (a fixed kernel, a ladder too short) counts as not noise.
    """
    if choice is None or not choice.scale.denoise:
        return False
    return bool(choice.quiet_rise <= TUNING.noise_rise) or noise_swamps_balls(choice)


def flattening(choice) -> bool:
    """Whether points the noise flattens are flagged (:attr:`FitPlan.flattening`): the residual is noise
    (:func:`noisy_residuals`) of at least ``TUNING.flattening_noise`` of the spacing."""
    return noisy_residuals(choice) and bool(choice.relative_noise >= TUNING.flattening_noise)


def noise_swamps_balls(scale) -> bool:
    """Whether the kernel choice ``scale`` (a :class:`heatcurv.choice.scale.ScaleChoice` or its report; None:
    no choice) measured noise above ``TUNING.strong_noise`` of its spacing, as thick as the operator's balls."""
    return scale is not None and bool(scale.relative_noise > TUNING.strong_noise)
