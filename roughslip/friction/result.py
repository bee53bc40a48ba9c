r"""The outcome of a pull, decoupled or coupled: one type, one vocabulary.

:func:`~roughslip.friction.pull.pull` (the decoupled model) and
:func:`~roughslip.coupling.coupled.couple` (the coupled one) both return a
:class:`PullResult`: the pull curve from its start (:class:`~roughslip.friction.events.Curve`,
one entry per event, the first the state at :math:`D_x = 0`), the event of the peak, the
states at the start and at the peak (:class:`PullState`), and the diagnostics of the solve.
What only one model has is nested in :attr:`PullResult.details`: :class:`DecoupledDetails`
(the bonds, the early stop, the error estimates, the precision) or :class:`CoupledDetails`
(the squeeze history, the bonds released before the pull, the block solver's counters).

The names of earlier versions (``fx_at_peak``, ``dx_lim``, ``fz0``, ``fx_peak``, the flat
``error_estimate`` or ``released``, ...) still work and warn (:class:`DeprecationWarning`),
each naming what replaces it; ``SlipResult`` and ``CoupledResult`` are this type.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from roughslip.friction.events import Curve, Event, EventKind


@dataclass(frozen=True)
class PullState:
    """One state of a pull on the grid (``[iy, ix]``): the normal and tangential forces, the
    contact sites and the stick sites (bonds that hold). ``fy`` is None in the x-only model
    (``pull.components = "x"``), whose bonds carry no y force."""

    fz: np.ndarray
    fx: np.ndarray
    contact: np.ndarray
    stick: np.ndarray
    fy: np.ndarray | None = None


@dataclass(frozen=True)
class DecoupledDetails:
    r"""What the decoupled pull has besides the common result (:class:`PullResult`).

    Attributes
    ----------
    lam : float
        The static coefficient :math:`\lambda` of the bonds.
    n_bonds : int
        The bonds of the squeeze.
    early_stopped : bool
        The exact early stop ended the break sequence.
    squeeze_seconds : float
        Of :attr:`PullResult.seconds`, those before the pull: 0, the squeeze is solved
        before the decoupled pull is called (as :attr:`CoupledDetails.squeeze_seconds`).
    precision : str
        Of the ``"inverse"`` method's matrix: ``"double"`` or ``"single"`` (empty for the
        other methods).
    error_estimate : float
        With ``pull(..., estimate_error=True)``: the estimated relative error of the friction
        force, ``solve_error_estimate + normal_error_estimate``, the errors of the pull's own
        solves and of the squeeze's normal forces it starts from; within a factor 3.2 of the
        true error on every verify scene. NaN when not estimated, and for the approximate
        ``"batch"`` method, whose error is a staircase in the batch size that no cheap
        comparison estimates.
    solve_error_estimate : float
        The pull's own part: :func:`~roughslip.friction.pull_estimates.refinement_estimate`
        (one step of iterative refinement on the peak state) under the break law, at the
        rounding level for ``"inverse"``; 0 under a law whose friction force
        :math:`\sum_i s_i\lambda f_{z,i}` takes no tangential solve.
    normal_error_estimate : float
        The squeeze's part, :func:`~roughslip.friction.pull_estimates.normal_share`.
    error_bound : float
        :math:`\hat\kappa\,\rho`, the condition estimate times the worst relative residual
        (:attr:`PullResult.residual`): an *estimate of a bound* on the relative error of the
        tangential forces, on the verify scenes never below the error of the friction force
        and up to :math:`7\cdot10^6` times above it.
    condition : float
        :math:`\hat\kappa`, the Lanczos estimate of the condition number of :math:`G_{xx}` on
        the bonds of the squeeze (the exact value bounds that of every later stick set).
    components : str
        The tangential model (``pull.components``): ``"x"`` or ``"xy"``.
    direction : float
        The drive's angle in the surface plane, degrees from x toward y.
    """

    lam: float = 0.2
    n_bonds: int = 0
    early_stopped: bool = False
    squeeze_seconds: float = 0.0
    precision: str = ""
    error_estimate: float = math.nan
    solve_error_estimate: float = math.nan
    normal_error_estimate: float = math.nan
    error_bound: float = math.nan
    condition: float = math.nan
    components: str = "x"
    direction: float = 0.0


@dataclass(frozen=True)
class CoupledDetails:
    """What the coupled model has besides the common result (:class:`PullResult`).

    ``contact_area``: the fraction of the grid in contact at :math:`D_x = 0`; ``released``:
    contact sites with no bond holding when the pull starts; ``depth``: :math:`D_z` after the
    squeeze; ``pull_control``: what the pull holds (``"depth"`` or ``"force"``);
    ``history``: how the contacts came to carry their bonds; ``squeeze_states``: states
    solved before the pull; ``squeeze_seconds``: of the whole solve's seconds, those before
    the pull; ``blas_seconds``: seconds in dense linear algebra; ``fallback``: why the block
    solver went on matrix-free, else ""; ``slip_iterations``: GMRES iterations of the solves
    with slip forces; ``states``: with ``record_states=True``, (D_x, f_z, f_x, gap, contact,
    stick) at every event.
    """

    contact_area: float = 0.0
    released: int = 0
    depth: float = math.nan
    pull_control: str = "depth"
    history: str = "bonded"
    squeeze_states: int = 0
    squeeze_seconds: float = math.nan
    blas_seconds: float = 0.0
    fallback: str = ""
    slip_iterations: int = 0
    states: list | None = None


#: names of earlier versions -> (what replaces each, how to get it)
_RENAMED = {
    "fx_at_peak": ("peak.fx", lambda r: r.peak.fx),
    "stick_at_peak": ("peak.stick", lambda r: r.peak.stick),
    "fx_peak": ("peak.fx", lambda r: r.peak.fx),
    "fz_peak": ("peak.fz", lambda r: r.peak.fz),
    "stick_peak": ("peak.stick", lambda r: r.peak.stick),
    "contact_peak": ("peak.contact", lambda r: r.peak.contact),
    "fz0": ("start.fz", lambda r: r.start.fz),
    "fx0": ("start.fx", lambda r: r.start.fx),
    "contact0": ("start.contact", lambda r: r.start.contact),
    "stick0": ("start.stick", lambda r: r.start.stick),
    "dx": ("curve.dx", lambda r: r.curve.dx),
    "fx": ("curve.fx", lambda r: r.curve.fx),
    "fz": ("curve.fz", lambda r: r.curve.fz),
    "dz": ("curve.dz", lambda r: r.curve.dz),
    "dx_lim": ("curve.dx[1:]", lambda r: r.curve.dx[1:]),
    "fx_lim": ("curve.fx[1:]", lambda r: r.curve.fx[1:]),
    "broken_site": ("curve.site[1:]", lambda r: r.curve.site[1:]),
    "kinds": ("curve.kind[1:]", lambda r: r.curve.kind[1:]),
    "peak_index": ("peak_event - 1", lambda r: r.peak_event - 1),
}


@dataclass(frozen=True)
class PullResult:
    """The outcome of a pull (module docstring).

    Attributes
    ----------
    friction_force : float
        The static friction force: the largest pull force of the path (under a law whose
        contact ends sliding, the decoupled model gives the force at full sliding).
    normal_force_at_peak : float
        :math:`F_z` at the peak.
    normal_force : float
        :math:`F_z` of the state the pull starts from.
    curve : Curve
        Every event from the start: :math:`D_x`, :math:`F_x`, :math:`F_z`, :math:`D_z`, kind
        and site; the first is the start (:data:`EventKind.START` at :math:`D_x = 0`). Empty
        when there is nothing to pull (no contact).
    peak_event : int
        The index of the peak in :attr:`curve` (0 for an empty curve).
    peak, start : PullState
        The states at the peak and at the start.
    converged : bool
        Every solve met its tolerance and the path was followed to its end.
    seconds, method, slip_law, residual, solves, message
        The whole solve's wall-clock time, the method that ran (``"auto"`` resolved), the
        slip law, the worst certified relative residual, the solves, and what happened.
    details : DecoupledDetails or CoupledDetails
        What one model has and the other not.
    """

    friction_force: float
    normal_force_at_peak: float
    normal_force: float
    curve: Curve
    peak_event: int
    peak: PullState
    start: PullState
    converged: bool
    seconds: float
    method: str
    slip_law: str
    residual: float
    solves: int
    message: str
    details: DecoupledDetails | CoupledDetails

    @property
    def pull_seconds(self) -> float:
        """Of :attr:`seconds`, those of the pull (after the squeeze)."""
        return self.seconds - self.details.squeeze_seconds

    @property
    def steps(self) -> int:
        """The events after the start."""
        return max(self.curve.dx.size - 1, 0)

    @property
    def peak_dx(self) -> float:
        """:math:`D_x` at the peak."""
        return float(self.curve.dx[self.peak_event]) if self.curve.dx.size else 0.0

    @property
    def friction_vector(self) -> tuple[float, float]:
        r"""The tangential force vector :math:`(F_x, F_y)` of the peak state, the sums of
        its forces (:math:`F_y = 0` in the x-only model); :attr:`friction_force` is its
        component along the drive."""
        fy = 0.0 if self.peak.fy is None else float(self.peak.fy.sum())
        return float(self.peak.fx.sum()), fy

    @property
    def events(self) -> list[Event]:
        """The events of :attr:`curve`, one :class:`~roughslip.friction.events.Event` each."""
        c = self.curve
        return [Event(float(c.dx[i]), float(c.fx[i]), float(c.fz[i]), c.kind[i],
                      int(c.site[i]), float(c.dz[i])) for i in range(c.dx.size)]

    def __getattr__(self, name: str) -> Any:
        """The names of earlier versions (module docstring), with a warning."""
        if name.startswith("__"):
            raise AttributeError(name)
        if name in _RENAMED:
            instead, get = _RENAMED[name]
            warnings.warn(f"PullResult.{name} is deprecated; use {instead}",
                          DeprecationWarning, stacklevel=2)
            return get(self)
        details = object.__getattribute__(self, "details")
        if name in {f.name for f in fields(details)}:
            warnings.warn(f"PullResult.{name} is deprecated; use details.{name}",
                          DeprecationWarning, stacklevel=2)
            return getattr(details, name)
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")


def start_curve(dx: np.ndarray, fx: np.ndarray, kinds: tuple[str, ...], sites: np.ndarray,
                normal_force: float, depth: float) -> Curve:
    """The curve of a decoupled pull from its events after the start: the start (at
    :math:`D_x = 0`, no force) first; :math:`F_z` and :math:`D_z` stay the squeeze's."""
    n = dx.size
    return Curve.x_only(np.concatenate([[0.0], dx]), np.concatenate([[0.0], fx]),
                        np.full(n + 1, float(normal_force)), np.full(n + 1, float(depth)),
                        (EventKind.START, *kinds), np.concatenate([[-1], sites]))


def _from_decoupled(old: dict[str, Any]) -> PullResult:
    """A :class:`PullResult` from the keywords of the decoupled result of earlier versions."""
    old = dict(old)
    dx = np.asarray(old.pop("dx_lim"), dtype=float)
    n = dx.size
    normal = float(old.pop("normal_force", 0.0))
    kinds = tuple(old.pop("kinds", ()) or (EventKind.BREAK,) * n)
    curve = start_curve(dx, np.asarray(old.pop("fx_lim"), dtype=float), kinds,
                        np.asarray(old.pop("broken_site"), dtype=np.int64), normal, math.nan)
    fx, stick = np.asarray(old.pop("fx_at_peak")), np.asarray(old.pop("stick_at_peak"))
    old.pop("steps", None)
    names = {f.name for f in fields(DecoupledDetails)}
    details = DecoupledDetails(**{k: old.pop(k) for k in list(old) if k in names})
    zero = np.zeros(fx.shape)
    return PullResult(
        friction_force=old.pop("friction_force"), normal_force_at_peak=normal,
        normal_force=normal, curve=curve, peak_event=old.pop("peak_index", -1) + 1 if n else 0,
        peak=PullState(zero, fx, stick, stick), start=PullState(zero, zero, stick, stick),
        converged=old.pop("converged"), seconds=old.pop("seconds"), method=old.pop("method"),
        slip_law=old.pop("slip_law", "break"), residual=old.pop("residual", 0.0),
        solves=old.pop("solves", 0), message=old.pop("message", ""), details=details,
        **old)  # anything left is not a field: the same TypeError as before


def _from_coupled(old: dict[str, Any]) -> PullResult:
    """A :class:`PullResult` from the keywords of the coupled result of earlier versions."""
    old = dict(old)
    events = list(old.pop("events"))
    curve = Curve.of(events) if events else Curve.empty()
    ff, at = old.pop("friction_force"), old.pop("peak_dx", 0.0)
    hits = [i for i, e in enumerate(events) if e.dx == at and e.fx == ff]
    names = {f.name for f in fields(CoupledDetails)}
    details = CoupledDetails(**{k: old.pop(k) for k in list(old) if k in names})
    return PullResult(
        friction_force=ff, normal_force_at_peak=old.pop("normal_force_at_peak"),
        normal_force=old.pop("normal_force"), curve=curve, peak_event=hits[0] if hits else 0,
        peak=PullState(old.pop("fz_peak"), old.pop("fx_peak"), old.pop("contact_peak"),
                       old.pop("stick_peak")),
        start=PullState(old.pop("fz0"), old.pop("fx0"), old.pop("contact0"), old.pop("stick0")),
        converged=old.pop("converged"), seconds=old.pop("seconds"), method=old.pop("method"),
        slip_law=old.pop("slip_law", "break"), residual=old.pop("residual", math.nan),
        solves=old.pop("solves"), message=old.pop("message", ""), details=details, **old)


class _Renamed(type):
    """The class of a result type of earlier versions: calling it builds a
    :class:`PullResult` from the old keywords, with a :class:`DeprecationWarning`, and every
    :class:`PullResult` is an instance of it."""

    def __instancecheck__(cls, obj: object) -> bool:
        return isinstance(obj, PullResult)

    def __call__(cls, **old: Any) -> PullResult:
        warnings.warn(f"{cls.__name__} is deprecated; the pull returns a PullResult",
                      DeprecationWarning, stacklevel=2)
        return cls.build(old)


class SlipResult(metaclass=_Renamed):
    """Deprecated: the decoupled pull's result type of earlier versions, now
    :class:`PullResult` (``SlipResult(**old_fields)`` still builds one)."""

    build = staticmethod(_from_decoupled)


class CoupledResult(metaclass=_Renamed):
    """Deprecated: the coupled model's result type of earlier versions, now
    :class:`PullResult` (``CoupledResult(**old_fields)`` still builds one)."""

    build = staticmethod(_from_coupled)


def renamed(module: str, name: str) -> type:
    """The result type of earlier versions ``name``, looked up in ``module``, with a
    :class:`DeprecationWarning` (for the modules' ``__getattr__``)."""
    warnings.warn(f"{module}.{name} is deprecated; use roughslip.friction.result.PullResult",
                  DeprecationWarning, stacklevel=3)
    return {"SlipResult": SlipResult, "CoupledResult": CoupledResult}[name]
