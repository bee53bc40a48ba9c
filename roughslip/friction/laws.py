r"""Slip laws: what a bond does once its tangential force reaches its strength.

Every law shares the failure criterion of a stick bond, :math:`|f_x| \le \lambda f_z`: two
affine constraint rows per stick site, :math:`\lambda f_z - f_x \ge 0` (event ``"slip+"``) and
:math:`\lambda f_z + f_x \ge 0` (``"slip-"``). A law says the rest:

* **what a failed bond carries**: its slip direction :math:`\boldsymbol\sigma` after an event,
  a unit vector in the tangential components of the model
  (:data:`~roughslip.friction.events.TANGENTIAL`), or zero for nothing
  (:meth:`SlipLaw.failed_direction`), and the force of a slipping bond,
  :math:`\mathbf f_t = \mathbf w f_z` with :math:`\mathbf w` from :meth:`SlipLaw.carried`;
* **its constraint rows** (:meth:`SlipLaw.stick_rows`) and how overloaded a bond is
  (:meth:`SlipLaw.overload`), which the event loop turns into events;
* **its reversal rule** (:attr:`SlipLaw.reverses`, :meth:`SlipLaw.turned_back`): whether a
  slipping bond whose slip the drive would turn around sticks again where it is (event
  ``"stick"``);
* **its decoupled pull**: the engine that runs it on a method's stick solver
  (:attr:`SlipLaw.engine`), and what that engine needs of the solver (:attr:`SlipLaw.needs`),
  from which the methods that run it follow
  (:meth:`roughslip.friction.pull.PullMethod.runs`).

The laws are registered in :data:`LAWS`, which the configuration reads for the choices and the
help of ``pull.slip_law``. docs/extending.md says how to add one.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import ClassVar

import numpy as np

from roughslip.errors import InputError
from roughslip.friction.breaking import break_sequence
from roughslip.friction.events import RATE_TIE, TANGENTIAL, TIE, EventKind
from roughslip.friction.sliding_single import slide_certified
from roughslip.friction.weakening import weaken
from roughslip.registry import Registry


class LawParameterError(InputError):
    """A slip law's own parameter is missing or breaks its rule; ``key`` names it, ``value``
    is what was given (None: nothing) and ``rule`` says what it must be."""

    def __init__(self, key: str, value: float | None, rule: str) -> None:
        self.key, self.value, self.rule = key, value, rule
        super().__init__(f"{key}: {rule}" if value is None else f"{key} = {value!r}: {rule}")


#: a constraint row: (event kind, where it applies, value at D = 0, rate in D, force scale)
Row = tuple[str, np.ndarray, np.ndarray, np.ndarray, float]


@dataclass(frozen=True)
class SlipLaw:
    r"""A slip law (module docstring). Subclass it and override what differs.

    Attributes
    ----------
    name
        Its name in :data:`LAWS` and in ``pull.slip_law``.
    failed
        What the run's notes call the contact sites without a bond when the pull starts
        (``"released"``, ``"slipping"``).
    curve
        What the plots call its pull curve (``"break sequence"``, ``"slip events"``).
    reverses
        A slipping bond whose slip the drive would turn around sticks again.
    slides
        Failed bonds carry force, so the contact ends sliding: the decoupled friction force
        is the sum of the forces they carry, which no tangential solve enters (its error is
        the normal forces' alone). Otherwise the friction force is the peak of the pull
        curve.
    engine
        Its decoupled pull, ``engine(bonds, options, t0) -> PullResult``, on the stick solver
        of ``options.method`` (:class:`~roughslip.linalg.stick.StickSolver`).
    needs
        What the engine needs of the stick solver beyond :math:`\varphi` on each stick set
        (:data:`roughslip.friction.pull.CAPABILITIES`). By default ``"tracked"``: a failed
        bond carries force. A law that needs nothing is a break sequence on :math:`\varphi`
        alone (failed bonds carry nothing and never stick again), which the matrix-free
        methods also run.
    couples
        The coupled model (:func:`~roughslip.coupling.coupled.couple`) runs it exactly.
    couples_vector
        The coupled model runs it with the traction vector
        (:func:`~roughslip.coupling.cone.couple_cone`, the faceted cone).
    lands
        Its decoupled pull records the state each burst lands in, at the drive (an event
        with site -1): :func:`roughslip.analysis.bursts.landing_curve` reads its curve.
    single
        The tangential models (:attr:`components`) in which its engine certifies its
        decisions against the exact operator, and so runs on an inexact inverse: a
        single-precision one (``pull(..., precision="single")``) or a compressed one
        (``method="hierarchical"``); empty when it has none.
    certified
        The tangential models in which its engine refines every solution and column it
        decides on against the exact operator, and so runs on a compressed inverse in double
        precision (``method="hierarchical"``), though not in single precision.
    components
        The tangential models its decoupled engine runs (``pull.components``,
        :data:`~roughslip.friction.bonds.TANGENTIAL_MODELS`): ``"x"``, the report's model, and
        ``"xy"`` for a law whose engine handles the traction vector.
    lam
        The static coefficient :math:`\lambda_s` once bound (:meth:`bind`; NaN before).
    """

    #: the law's own parameters: keywords of :func:`~roughslip.friction.pull.pull` and keys
    #: of ``[pull]``
    params: ClassVar[tuple[str, ...]] = ()

    name: str
    failed: str = "released"
    curve: str = "events"
    reverses: bool = False
    slides: bool = False
    couples: bool = True
    couples_vector: bool = False
    lands: bool = False
    single: tuple[str, ...] = ()
    certified: tuple[str, ...] = ()
    components: tuple[str, ...] = ("x",)
    engine: Callable[..., object] | None = None
    needs: frozenset[str] = frozenset({"tracked"})
    lam: float = math.nan

    @property
    def sequence(self) -> bool:
        r"""Its decoupled pull is a break sequence on :math:`\varphi` alone: failed bonds
        carry nothing and never stick again (it needs nothing of a stick solver)."""
        return not self.needs

    def bind(self, lam: float, **params: float | None) -> SlipLaw:
        """The law with its static coefficient ``lam`` and its own parameters (``None``: not
        given); :class:`~roughslip.errors.InputError` names a parameter the law does not
        have, or one it needs and lacks."""
        for key, value in params.items():
            if value is not None and key not in self.params:
                raise LawParameterError(key, value, f"slip_law = {self.name!r} has no such "
                                        "parameter" + (f" (it has {', '.join(self.params)})"
                                                       if self.params else ""))
        return replace(self, lam=float(lam))

    def failed_direction(self, kind: str) -> np.ndarray:
        r"""The slip direction :math:`\boldsymbol\sigma` a bond keeps after the failure event
        ``kind`` (``"slip+"`` or ``"slip-"``): a unit vector of the tangential components
        (:data:`~roughslip.friction.events.TANGENTIAL`), or the zero vector when it carries
        no tangential force (this law)."""
        return np.zeros(len(TANGENTIAL))

    def carried(self, lam: float, sigma: np.ndarray) -> np.ndarray:
        r""":math:`\mathbf w` of the slipping bonds with slip directions ``sigma`` (unit
        vectors on the last axis): they carry :math:`\mathbf f_t = \mathbf w f_z`."""
        return lam * sigma

    def stick_rows(self, lam: float, S: np.ndarray, f0: tuple[np.ndarray, np.ndarray],
                   f1: tuple[np.ndarray, np.ndarray], scale: float) -> list[Row]:
        r"""The constraints of the stick sites ``S`` for forces :math:`f = f^0 + D f^1`
        (``(f_z, f_x)`` pairs): :math:`\lambda f_z \mp f_x \ge 0`."""
        (fz0, fx0), (fz1, fx1) = f0, f1
        return [(EventKind.SLIP_PLUS, S, lam * fz0 - fx0, lam * fz1 - fx1, scale),
                (EventKind.SLIP_MINUS, S, lam * fz0 + fx0, lam * fz1 + fx1, scale)]

    def turned_back(self, slipping: np.ndarray, sigma: np.ndarray, rate: np.ndarray,
                    rigid: np.ndarray) -> int | None:
        r"""The reversal rule: the slipping bond (flat index) that sticks again, or None.

        A bond slipping in direction :math:`\boldsymbol\sigma` lags behind the rigid surface,
        :math:`\boldsymbol\sigma\cdot(\partial\mathbf u_t/\partial D - \mathbf v) \le 0`,
        with ``rate`` the :math:`\partial\mathbf u_t/\partial D` of the bonds and ``rigid``
        the surface's tangential rate :math:`\mathbf v` (the drive's unit vector in a pull,
        zero when the depth is driven), vectors of the tangential components
        (:data:`~roughslip.friction.events.TANGENTIAL`) on the last axis. Under a law that
        :attr:`reverses`, the bond whose slip would run against its force by the most (above
        ``RATE_TIE``; ties to the lowest index) sticks again where it is: its force is
        continuous, starting at its bound and moving inwards.
        """
        if not self.reverses:
            return None
        back = np.where(slipping, (sigma * (rate - rigid)).sum(axis=-1), -np.inf).ravel()
        top = float(back.max())
        if not top > RATE_TIE:
            return None
        return int(np.flatnonzero(back >= top - TIE * max(1.0, top))[0])

    def overload(self, lam: float, S: np.ndarray, fz: np.ndarray, fx: np.ndarray
                 ) -> np.ndarray:
        r""":math:`|f_x|/(\lambda f_z)` on the stick sites ``S`` (infinite where
        :math:`f_z \le 0`), 0 elsewhere: above 1 a bond is overloaded."""
        over = np.zeros(fz.shape)
        np.divide(np.abs(fx), lam * fz, out=over, where=S & (fz > 0))
        over[S & (fz <= 0)] = np.inf
        return over


@dataclass(frozen=True)
class BreakLaw(SlipLaw):
    """The report's law: a failed bond breaks and carries nothing after."""

    needs: frozenset[str] = frozenset()


@dataclass(frozen=True)
class CoulombLaw(SlipLaw):
    r"""Coulomb friction: a failed bond slips in the direction of its force, carrying
    :math:`f_x = \sigma\lambda f_z` as :math:`f_z` changes, and sticks again where it is
    when the drive would turn its slip around."""

    def failed_direction(self, kind: str) -> np.ndarray:
        return np.array([1.0 if kind == EventKind.SLIP_PLUS else -1.0])


@dataclass(frozen=True)
class SlipWeakeningLaw(SlipLaw):
    r"""Linear slip-weakening friction (:mod:`roughslip.friction.weakening`): a failed bond
    slips, and its strength falls from :math:`\lambda_s f_z` (``lam``) to
    :math:`\lambda_d f_z` (``lam_dynamic``) over the slip :math:`d_c` (``slip_distance``).
    The break law is its limit :math:`\lambda_d = 0,\ d_c \to 0`; the Coulomb law is
    :math:`\lambda_d = \lambda_s`. Under coupling its constraint is bilinear
    (:math:`\lambda(\delta) f_z` with both varying): the coupled model follows it with a
    certified path-follower (:mod:`roughslip.coupling.weakening`)."""

    params: ClassVar[tuple[str, ...]] = ("lam_dynamic", "slip_distance")
    lam_dynamic: float = math.nan
    slip_distance: float = math.nan

    def bind(self, lam: float, **params: float | None) -> SlipLaw:
        super().bind(lam, **params)
        ld, dc = params.get("lam_dynamic"), params.get("slip_distance")
        if ld is None or dc is None:
            raise LawParameterError("lam_dynamic" if ld is None else "slip_distance", None,
                                    f"slip_law = {self.name!r} needs lam_dynamic and "
                                    "slip_distance")
        if not (isinstance(ld, int | float) and math.isfinite(ld) and 0 <= ld <= lam):
            raise LawParameterError("lam_dynamic", ld, "must satisfy 0 <= lam_dynamic <= lam "
                                    f"(= {lam!r})")
        if not (isinstance(dc, int | float) and math.isfinite(dc) and dc > 0):
            raise LawParameterError("slip_distance", dc, "must be a finite number > 0")
        return replace(self, lam=float(lam), lam_dynamic=float(ld), slip_distance=float(dc))

    def failed_direction(self, kind: str) -> np.ndarray:
        return np.array([1.0 if kind == EventKind.SLIP_PLUS else -1.0])


#: the slip laws, by name (the configuration's ``pull.slip_law``)
LAWS: Registry[SlipLaw] = Registry("slip law")

LAWS.register("break", "a failed bond carries no force (the report's law)")(BreakLaw(
    "break", failed="released", curve="break sequence", single=("x", "xy"),
    engine=break_sequence,
    components=("x", "xy")))
LAWS.register("coulomb", "a failed bond slips, carrying lam f_z against the pull")(CoulombLaw(
    "coulomb", failed="slipping", curve="slip events", reverses=True, slides=True,
    engine=slide_certified, needs=frozenset({"tracked"}), components=("x", "xy"),
    couples_vector=True, single=("x",)))
LAWS.register("slip-weakening", "a failed bond slips, its strength falling from lam f_z to "
              "lam_dynamic f_z over the slip slip_distance")(SlipWeakeningLaw(
    "slip-weakening", failed="slipping", curve="slip events", reverses=True, couples=True,
    lands=True, engine=weaken, certified=("x",),
    needs=frozenset({"tracked", "growing", "shifted", "indefinite"})))
