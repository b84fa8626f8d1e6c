"""What a fit of one walk returns: :class:`FitResult`, its estimates, uncertainty, residuals and
fitted gait (:func:`toywalk.sysid.fit.fit`; each walk of a joint fit,
:func:`toywalk.sysid.walks.fit_walks`). Read off the solved problem by
:meth:`toywalk.sysid.problem.FitProblem.result`; written as the fit file of docs/formats.md."""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

import numpy as np
from toywalk.model.parameters import Params

if TYPE_CHECKING:
    from .fit import PeriodicityTest

__all__ = ["FitResult"]


@dataclasses.dataclass
class FitResult:
    """Estimates, uncertainty, residuals and the fitted gait.

    Attributes
    ----------
    free : list of str
        The fitted parameters (PARAMETER_NAMES names).
    estimates, std : dict of str to float
        Estimates and standard errors of the free parameters and the nuisance offsets.
    covariance, correlation : ndarray, shape (n, n)
        Over ``free``, then :data:`OFFSETS`, :data:`POSITION_NUISANCES` (m: the first measured
        contact, where the walk has contact positions) and ``time_offset`` (s: the model's first
        heel strike against the measured one) (``names``).
    names : list of str
    noise_sd : dict of str to float
        Noise SD per signal (rad) used in the final pass; ``noise_source`` says where it came from.
        With contact positions also :data:`~toywalk.sysid.problem.CONTACT_KEYS` (m), from ``contact_source``.
    residual_rms : dict of str to float
        RMS residual per signal (rad), of the step durations and heel strikes (s), and of the
        contact positions along and across the ramp (m, :data:`~toywalk.sysid.problem.CONTACT_KEYS`).
    residual_rms_by_phase : dict of str to list of float
        RMS residual per signal in ``_PHASE_BINS`` bins of the step phase.
    chi2 : float
        Sum of squared whitened residuals; ``n_residuals`` of them.
    success : bool
    status : str
        IPOPT's return status.
    params : Params
        The walker with the estimates.
    gait : dict
        The fitted gait: fixed point (public names), step times, eigenvalues, max |eigenvalue|,
        map (step or stride).
    warnings : list of str
        Identifiability, bounds and cross-check findings, with numbers.
    jacobian_check : dict
        Largest relative difference between the AD and the finite-difference residual Jacobian
        per free parameter.
    model : str
        'periodic' or 'transient' (:data:`toywalk.sysid.problem.MODELS`).
    initial_state : dict
        Transient model: the fitted state just after the first measured heel strike (public names,
        physical description, its stance leg ``stance``); empty for the periodic model.
    contact_source : str
        Where the contact positions' SDs came from ('file', 'given', 'estimated from
        residuals'), or 'none' when the walk has no contact positions.
    residuals : ndarray, shape (n_obs,)
        Model minus measurement of every angle observation (rad), in the order of
        :class:`toywalk.sysid.measurement.Observations`.
    model_durations : ndarray, shape (n_steps,)
        The model's duration of each measured step (s).
    options : dict
        The fit's set-up (model, offsets, mesh, strikes, iteration cap), to repeat it.
    aligned_rms : dict of str to float or None
        A fit on the model's strikes from the aligned stage: the angle residuals' RMS per signal
        (rad) at the first aligned stage's solution, the measured strikes taken as exact (a fit
        that ends far above it has found another minimum of the time offset); None otherwise.
    seconds : float
        Wall time of the fit (s).
    exposure_s : float
        The shutter time each sample was read over (s; the trajectory's ``exposure_s``, 0: at its
        time; :func:`toywalk.sysid.measurement.shutter_reads`).
    undetermined : list of str
        The estimates the data do not determine (the information singular along a direction they
        share): their standard errors, covariances and correlations are NaN, never a number.
    periodicity : toywalk.sysid.fit.PeriodicityTest or None
        The test that chose this fit's model, where ``fit(model='auto')`` made one.
    shared_widening : dict of str to float
        Each free parameter's standard error over the one it would have if every sample's error
        were its own, where the errors the samples share by phase (the file's ``*_phase_sd``)
        widen it by more than 1 %: ``std`` and ``covariance`` hold them
        (:func:`toywalk.sysid.problem.shared_covariance`).
    """

    free: list
    estimates: dict
    std: dict
    covariance: np.ndarray
    correlation: np.ndarray
    names: list
    noise_sd: dict
    noise_source: str
    residual_rms: dict
    residual_rms_by_phase: dict
    chi2: float
    n_residuals: int
    success: bool
    status: str
    iterations: int
    params: Params
    gait: dict
    warnings: list
    jacobian_check: dict
    priors: dict = dataclasses.field(default_factory=dict)
    solution: np.ndarray = dataclasses.field(repr=False, default=None)
    model: str = "periodic"
    initial_state: dict = dataclasses.field(default_factory=dict)
    sigma: np.ndarray = dataclasses.field(repr=False, default=None)
    start_dof: int = 0
    contact_source: str = "none"
    residuals: np.ndarray = dataclasses.field(repr=False, default=None)
    model_durations: np.ndarray = dataclasses.field(repr=False, default=None)
    options: dict = dataclasses.field(default_factory=dict)
    aligned_rms: dict | None = None
    n_w: int = dataclasses.field(repr=False, default=0)
    seconds: float = 0.0
    exposure_s: float = 0.0
    undetermined: list = dataclasses.field(default_factory=list)
    periodicity: PeriodicityTest | None = dataclasses.field(repr=False, default=None)
    shared_widening: dict = dataclasses.field(default_factory=dict)

    def to_json(self) -> dict:
        """JSON-ready dictionary (the fit file of docs/formats.md, "Fit": estimates, std, covariance, ...; the
        ``periodicity`` test where one chose the model)."""
        out = {
            "status": self.status, "success": self.success, "iterations": self.iterations,
            "model": self.model, "initial_state": self.initial_state, "free": self.free,
            "estimates": self.estimates, "std": self.std,
            "names": self.names, "covariance": self.covariance.tolist(),
            "correlation": self.correlation.tolist(),
            "noise_sd": self.noise_sd, "noise_source": self.noise_source,
            "contact_source": self.contact_source, "exposure_s": self.exposure_s,
            "residual_rms": self.residual_rms, "residual_rms_by_phase": self.residual_rms_by_phase,
            "chi2": self.chi2, "n_residuals": self.n_residuals,
            "reduced_chi2": self.chi2 / max(self.n_residuals - len(self.names) - self.start_dof, 1),
            "gait": self.gait, "warnings": self.warnings, "jacobian_check": self.jacobian_check,
            "undetermined": self.undetermined, "shared_widening": self.shared_widening,
            "priors": {n: list(v) for n, v in self.priors.items()},
            "options": self.options, "params": self.params.to_dict(),
            "units": {"angles": "rad", "durations": "s", "contact positions": "m",
                      "parameters": "SI (docs/formats.md)"},
        }
        if self.periodicity is not None:
            out["periodicity"] = self.periodicity.to_json()
        return out

