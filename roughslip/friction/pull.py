r"""Horizontal pull and slip of a squeezed contact, decoupled model (docs/theory/pull.rst#break-law;
[Report2003] §4.6-4.7).

After the squeeze every contact site (``f_z > 0``) is a bond. The rigid surface is pulled by
:math:`D_x`: bonded (stick) sites have :math:`u_x = D_x`, other sites carry no tangential force,
so on the stick set :math:`S`

.. math:: G_{xx}[S,S]\,\varphi = 1_S, \qquad f_x = D_x\,\varphi, \qquad F_x = D_x \sum_S \varphi.

Break law
    The report's model, corrected by erratum T17 (docs/theory/errata.rst#erratum-t17) and
    erratum T18 (docs/theory/errata.rst#erratum-t18).
    The bond with the largest :math:`|f_x|/(\lambda f_z)` breaks next; it breaks at
    :math:`D_{x,\rm lim} = 1/\max_i |\varphi_i|/(\lambda f_{z,i})` and pull force
    :math:`F_{x,\rm lim} = D_{x,\rm lim} \sum_S\varphi`; its force drops to zero and the stick set
    shrinks by one site ("repeat from 3"). The static friction force is
    :math:`F_{\rm friction} = \max F_{x,\rm lim}`. Ties (within a relative 1e-9) go to the lowest
    flat index. Because every later :math:`F_{x,\rm lim} \le \lambda \sum_S f_z`, the sequence may
    stop, exactly, once that bound falls below the best value found (``early_stop``).

Coulomb law
    A slipping site carries :math:`f_x = \pm\lambda f_z` instead of 0. Between events all forces
    are affine in :math:`D_x`; the next stick site to reach its bound slips (see
    :func:`pull`). For a Hertz contact this is Cattaneo–Mindlin
    (docs/methods.rst#cattaneo-mindlin).

Methods (all exact except ``"batch"``)
    ``"literal"``: the report's algorithm done literally, one CG solve from zero per break, all
    bonds. The reference; slow.
    ``"inverse"``: the inverse of :math:`G_{xx}[S,S]`, updated by delayed blocks of rank-one
    removals applied as one symmetric rank-k product (BLAS-3); :math:`\varphi` is updated in
    :math:`O(n)` per break and certified against the FFT operator after every block. Needs
    one :math:`n \times n` matrix of doubles, compacted in place as bonds break (checked
    before starting, see :func:`inverse_memory_bytes`); with ``precision="single"`` (break
    law) one of floats, with certified decisions (:mod:`roughslip.friction.breaking_single`).
    ``"cg"``: matrix-free; per break a warm-started CG solve of the correction, with the early
    stop. Memory :math:`O(N^2)`.
    ``"batch"``: approximate; breaks the ``batch_size`` sites with the largest ratios per solve.
    Biased low, with no error estimate: its error is a staircase in the batch size
    (docs/methods.rst#estimates-against-truth).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from roughslip.contact.squeeze import NormalResult
from roughslip.errors import InputError
from roughslip.friction import result as _result
from roughslip.friction.bonds import TANGENTIAL_MODELS, Bonds, BreakCurve, PullOptions
from roughslip.friction.breaking import break_batch, break_cg, break_literal
from roughslip.friction.cone import FACETS, MAX_FACETS, MIN_FACETS
from roughslip.friction.events import TIE, plane_direction
from roughslip.friction.laws import LAWS, SlipLaw
from roughslip.friction.pull_estimates import (  # noqa: F401  (public here too)
    REFINE_TOL,
    bond_spectrum,
    normal_share,
    refinement_estimate,
)
from roughslip.friction.response import CompressedResponse
from roughslip.friction.result import PullResult, PullState
from roughslip.linalg import lapack64
from roughslip.linalg.hierarchical import HierarchicalInverse
from roughslip.linalg.inverse import UpdatableInverse, inverse_bytes
from roughslip.linalg.memory import available_bytes
from roughslip.linalg.stick import SolverFactory
from roughslip.linalg.threads import blas_threads
from roughslip.registry import Registry

#: names kept for code written against earlier versions: what replaces each
_DEPRECATED = {
    "SLIP_LAWS": ("roughslip.friction.laws.LAWS.names()", lambda: LAWS.names()),
    "TIE_TOL": ("roughslip.friction.events.TIE (the tie rule is events.argext)", lambda: TIE),
    "SlipResult": ("roughslip.friction.result.PullResult", lambda: _result.SlipResult),
}


def __getattr__(name: str):
    """The deprecated names of this module, with a :class:`DeprecationWarning` that says
    what replaces each."""
    if name in _DEPRECATED:
        import warnings

        instead, value = _DEPRECATED[name]
        warnings.warn(f"roughslip.friction.pull.{name} is deprecated; use {instead}",
                      DeprecationWarning, stacklevel=2)
        return value()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


#: what a method's stick solver can give beyond :math:`\varphi` on each stick set, and so what
#: a slip law may need of it (:attr:`~roughslip.friction.laws.SlipLaw.needs`):
#:
#: * ``"tracked"``: solutions kept through the changes, with values held by removed unknowns
#:   (slipping bonds that carry force);
#: * ``"growing"``: unknowns added to the set by bordering (a bond that sticks again keeping
#:   its weakening state);
#: * ``"shifted"``: shifts of a diagonal entry (a bond that starts or stops weakening);
#: * ``"indefinite"``: a symmetric matrix that is not positive definite.
CAPABILITIES = ("tracked", "growing", "shifted", "indefinite")


@dataclass(frozen=True)
class PullMethod:
    r"""A pull method, with what it can do (the capabilities :func:`pull` and ``auto`` read;
    no method name is compared anywhere else).

    A method either provides a stick solver (:attr:`solver`, the protocol
    :class:`~roughslip.linalg.stick.StickSolver`), on which each slip law's own engine runs
    (:attr:`~roughslip.friction.laws.SlipLaw.engine`), or a matrix-free engine of its own
    (:attr:`run`), which solves for :math:`\varphi` on each stick set afresh and so runs only
    the laws that need nothing more (the break law). The laws a method runs follow from
    :attr:`offers` and each law's :attr:`~roughslip.friction.laws.SlipLaw.needs`
    (:meth:`runs`).

    Attributes
    ----------
    name
        Its name in :data:`METHODS`.
    exact
        Gives the exact pull curve (up to the solver tolerance).
    dense
        Works on an n x n matrix: ``auto`` takes it while its matrix fits in memory
        (:func:`inverse_memory_bytes`), below the :attr:`above` of any other method.
    blas
        Its time goes to BLAS, as a dense method's does: BLAS gets the threads, and the FFTs
        of its certification one thread (two thread pools spinning on the same cores slow
        each other down).
    solver
        The stick solver's factory (the signature of
        :class:`~roughslip.linalg.inverse.UpdatableInverse`), or None.
    run
        ``run(bonds, options, t0) -> PullResult``: a matrix-free engine, or None.
    offers
        What the solver gives (:data:`CAPABILITIES`).
    precisions
        The precisions of its stored matrix (``"single"``: with certified decisions, for
        the laws that have them, :attr:`~roughslip.friction.laws.SlipLaw.single`).
    tiny
        ``auto`` takes it for at most this many bonds (0: by the other rules).
    above
        ``auto`` takes it from this many bonds on, before the dense methods, where it was
        measured faster than they are and its memory fits (0: only once no dense method
        fits; docs/benchmarks.md). Measured on open rough contacts at 20 % with one and two
        BLAS threads (the crossover came earlier on one); periodic grids, whose blocks have
        higher ranks, were not measured. It holds for break sequences (the laws that need
        nothing of the solver beyond the stick set); a law whose pull is an event path (the
        Coulomb law: an FFT product per event on either inverse, and the certification's
        refinements on this one) takes it only once no dense method fits.
    auto
        ``auto`` may choose it.
    early_stop
        It stops exactly once no later state can exceed the best (``pull.early_stop``).
    estimate
        Its friction force has the refinement error estimate (``estimate_error``).
    chooses
        It is no method of its own but the choice among the others (``auto``,
        :func:`choose_method`).
    inexact
        Its stick solver's inverse carries an error beyond rounding (a compressed one): it runs
        only the laws whose engines certify or refine their decisions against the exact
        operator (:attr:`~roughslip.friction.laws.SlipLaw.single`,
        :attr:`~roughslip.friction.laws.SlipLaw.certified`).
    components
        The tangential models it runs (``pull.components``,
        :data:`~roughslip.friction.bonds.TANGENTIAL_MODELS`).
    """

    name: str
    exact: bool
    dense: bool
    blas: bool = False
    solver: SolverFactory | None = None
    run: Callable[..., PullResult] | None = None
    offers: frozenset[str] = frozenset()
    precisions: tuple[str, ...] = ("double",)
    tiny: int = 0
    above: int = 0
    auto: bool = True
    early_stop: bool = True
    estimate: bool = True
    chooses: bool = False
    inexact: bool = False
    components: tuple[str, ...] = ("x",)

    def runs(self, law: SlipLaw, components: str = "x") -> bool:
        r"""Whether it runs ``law``: on a stick solver, a law with an engine that needs
        nothing the solver does not offer; matrix-free, a law that needs nothing (a break
        sequence on :math:`\varphi` alone). An :attr:`inexact` solver runs only the laws with
        certified decisions. A method that :attr:`chooses` runs nothing itself. The tangential
        model ``components`` must be one of the method's and the law's."""
        if components not in self.components or components not in law.components:
            return False
        if self.solver is not None:
            return (law.engine is not None and law.needs <= self.offers
                    and (components in law.single or components in law.certified
                         or not self.inexact))
        return self.run is not None and not law.needs


#: the pull methods, by name (the configuration's ``pull.method``)
METHODS: Registry[PullMethod] = Registry("pull method")


#: the precisions of a stored matrix (``pull(..., precision=...)``)
PRECISIONS = ("auto", "double", "single")


def inverse_memory_bytes(n: int, block: int = 128, precision: str = "double") -> int:
    """Peak memory of the ``"inverse"`` method for ``n`` bonds (bytes): one n x n matrix of
    doubles (``precision="single"``: of floats), compacted in place, plus the larger of the
    factorisation's work panels and the O(n block) work arrays of the pull, and a reserve
    (:func:`~roughslip.linalg.inverse.inverse_bytes`)."""
    return inverse_bytes(n, lower=True, block=block, itemsize=4 if precision == "single" else 8)


def _law(slip_law: str | SlipLaw) -> SlipLaw:
    """A slip law given by name or as the object."""
    return LAWS.get(slip_law, "slip_law") if isinstance(slip_law, str) else slip_law


def _method(method: str | PullMethod) -> PullMethod:
    """A pull method given by name or as the object."""
    return METHODS.get(method) if isinstance(method, str) else method


def single_ok(slip_law: str | SlipLaw, method: str | PullMethod = "inverse",
              components: str = "x") -> bool:
    """Whether ``method`` runs ``slip_law`` on a single-precision matrix in the tangential
    model ``components``: the law has certified decisions there
    (:attr:`~roughslip.friction.laws.SlipLaw.single`) and the method stores its matrix in
    single precision (``"auto"``: some method does)."""
    law = _law(slip_law)
    if components not in law.single:
        return False
    m = _method(method)
    if m.chooses:
        return any(METHODS.get(n).runs(law, components)
                   and "single" in METHODS.get(n).precisions for n in METHODS)
    return m.runs(law, components) and "single" in m.precisions


def choose_precision(n: int, memory: int | None = None, slip_law: str | SlipLaw = "break",
                     block: int = 128, method: str | PullMethod = "inverse",
                     per_point: int = 1, components: str = "x") -> str:
    """The precision ``"auto"`` picks for the matrix of ``n`` bonds given ``memory`` bytes:
    double when it fits, else single when that fits and the law and the method have it
    (:func:`single_ok`), else double (whose memory check then says what would fit). The
    memory is :func:`inverse_memory_bytes` for a dense method, the stick solver's estimate
    for another (with ``per_point`` unknowns at each point, the tangential components)."""
    memory = available_bytes() if memory is None else memory
    m = _method(method)
    law = _law(slip_law)
    if (_matrix_bytes(m, n, "double", block, per_point, law) <= memory
            or not single_ok(slip_law, method, components)):
        return "double"
    return ("single" if _matrix_bytes(m, n, "single", block, per_point, law) <= memory
            else "double")


def _matrix_bytes(m: PullMethod, n: int, precision: str, block: int = 128,
                  per_point: int = 1, law: SlipLaw | None = None) -> int:
    """The memory of ``m``'s matrices for ``n`` unknowns in ``precision``:
    :func:`inverse_memory_bytes` for a dense method, the stick solver's estimate for
    another (``per_point`` unknowns at each point: the tangential components). A ``law``
    whose matrix grows or shifts (slip-weakening) takes the dense inverse with spare rows
    (:func:`~roughslip.linalg.inverse.inverse_bytes`), and one whose bursts read the response
    :math:`G_{xx}^{-1}` on all bonds adds what they hold: two more such inverses beside a
    dense one, the compressed response beside a compressed one
    (:mod:`roughslip.friction.response`)."""
    full = law is not None and not law.needs <= {"tracked"}
    bursts = law is not None and law.lands
    if m.dense or m.solver is None:
        if not full:
            return inverse_memory_bytes(n, block, precision)
        return (3 if bursts else 1) * inverse_bytes(n, block=block)
    k = {"per_point": per_point} if per_point > 1 else {}
    own = m.solver.memory_bytes(n, itemsize=4 if precision == "single" else 8, **k)
    return own + (CompressedResponse.memory_bytes(n) if bursts else 0)


def _fits(m: PullMethod, n: int, law: SlipLaw, precision: str, memory: int,
          per_point: int = 1, components: str = "x") -> bool:
    """Whether ``m``'s matrix for ``n`` bonds fits in ``memory`` in a precision that
    ``precision`` (``"auto"``: any) and the law allow (single: :func:`single_ok`)."""
    return any(_matrix_bytes(m, n, p, per_point=per_point, law=law) <= memory
               for p in m.precisions
               if precision in ("auto", p) and (p == "double"
                                                or single_ok(law, m, components)))


def coulomb_force_at(result: PullResult, dx: float | np.ndarray) -> np.ndarray:
    """Pull force :math:`Q(D_x)` on the exact piecewise-linear Coulomb curve.

    Before the first slip event :math:`Q = K D_x` with the full-stick stiffness. The states
    of an avalanche are recorded at their own limits, below the drive that set it off; the
    curve under a monotone drive is the envelope of the events not passed by the drive.
    """
    if not LAWS.get(result.slip_law).slides:
        raise InputError("coulomb_force_at needs a result of a law whose bonds slip")
    x, y = result.curve.dx[1:], result.curve.fx[1:]
    keep = x >= np.maximum.accumulate(x) if x.size else np.zeros(0, bool)
    xs = np.concatenate([[0.0], x[keep]])
    ys = np.concatenate([[0.0], y[keep]])
    return np.interp(dx, xs, ys, right=result.friction_force)


def check_friction(lam: float, slip_law: str | SlipLaw, coupled: bool = False) -> None:
    """Raise :class:`InputError` unless ``lam`` is a finite number > 0 and ``slip_law`` a law
    of :data:`~roughslip.friction.laws.LAWS` (by name or object; the pull, the coupled model
    and the indentation share the rule), which the coupled model runs when ``coupled``."""
    if not (isinstance(lam, int | float) and math.isfinite(lam) and lam > 0):
        raise InputError(f"lam = {lam!r}: must be a finite number > 0")
    law = _law(slip_law)
    if coupled and not law.couples:
        raise InputError(f"slip_law = {slip_law!r}: the coupled model has no exact path for "
                         "it (its strength and f_z both vary, a bilinear constraint); use "
                         "the decoupled pull")


def check_direction(components: str, direction: float) -> tuple[tuple[str, ...], float]:
    """The tangential components of the model ``components``
    (:data:`~roughslip.friction.bonds.TANGENTIAL_MODELS`) and the drive's angle in degrees;
    :class:`InputError` names the key whose rule is broken: an unknown model, a non-finite
    angle, or an angle other than 0 in the x-only model (it pulls along x alone)."""
    if components not in TANGENTIAL_MODELS:
        raise InputError(f"pull.components = {components!r}: must be one of "
                         f"{', '.join(repr(c) for c in TANGENTIAL_MODELS)}")
    if not (isinstance(direction, int | float) and math.isfinite(direction)):
        raise InputError(f"pull.direction = {direction!r}: must be a finite angle in degrees")
    if components == "x" and direction != 0:
        raise InputError(f"pull.direction = {direction!r}: the x-only model "
                         "(pull.components = 'x') pulls along x alone; use components = 'xy' "
                         "for another drive direction")
    return TANGENTIAL_MODELS[components], float(direction)


def turned(res: PullResult, components: str, direction: float) -> PullResult:
    r"""The pull of the traction vector on an isotropic half-space (:math:`\nu = 0`) from the
    x-only model's pull ``res`` along the drive: there :math:`G_{xy} = 0` and
    :math:`G_{xx} = G_{yy}` (docs/theory/pull.rst#traction-vector), so every force of every
    state, stick or slipping, points along the drive :math:`\hat{\mathbf e}` and the bonds'
    forces are the x-only model's times :math:`\hat{\mathbf e}`. The curve (along the drive)
    and the friction force are unchanged, exactly, under every slip law."""
    e = plane_direction(direction)

    def vector(state: PullState) -> PullState:
        return replace(state, fx=state.fx * e[0], fy=state.fx * e[1])

    return replace(res, peak=vector(res.peak), start=vector(res.start),
                   details=replace(res.details, components=components, direction=direction),
                   message="nu = 0: the x-only model along the drive, turned (G_xy = 0, "
                           f"G_xx = G_yy); {res.message}")


def _no_vector(law: SlipLaw, components: str) -> InputError:
    """The refusal of a law that has no exact pull of the traction vector at nu > 0."""
    return InputError(f"pull.components = {components!r}: slip_law = {law.name!r} has no "
                      "exact pull of the traction vector at nu > 0 (its slip directions "
                      "turn); use components = 'x', nu = 0 or slip_law "
                      + ", ".join(repr(m) for m in LAWS.names()
                                  if components in LAWS.get(m).components))


def methods_for(slip_law: str | SlipLaw, components: str = "x") -> list[str]:
    """The pull methods that run ``slip_law`` in the tangential model ``components``
    (:meth:`PullMethod.runs`), and ``"auto"``, which chooses among them."""
    law = _law(slip_law)
    return [n for n in METHODS.names()
            if METHODS.get(n).runs(law, components) or METHODS.get(n).chooses]


def choose_method(n: int, memory: int | None = None, slip_law: str | SlipLaw = "break",
                  precision: str = "auto", components: str = "x") -> str:
    """The exact method ``"auto"`` picks for ``n`` bonds given ``memory`` bytes, among those
    that run ``slip_law`` and that ``auto`` may choose (:attr:`PullMethod.auto`), by their
    capabilities, in the order of :data:`METHODS`.

    A law that only dense methods run gets the first of them, which checks its memory
    itself. From the bond count where a method that is not dense was measured faster than the
    dense ones (:attr:`PullMethod.above`: the compressed inverse, for break sequences),
    ``auto`` takes that method whenever its memory fits. Otherwise, ``precision="single"``
    for a law with certified decisions gets the first dense method, which checks its memory
    itself. Otherwise a method
    made for tiny contacts takes them (:attr:`PullMethod.tiny`, the literal algorithm); then
    a dense method whenever its matrix fits in memory (in double or, where the law and the
    method have it, single precision) and the LAPACK can index it (for 3 271 bonds the
    inverse was about 100 times faster than one warm-started CG solve per break,
    docs/benchmarks.md); otherwise the first other exact method whose memory fits (a
    compressed inverse, by its estimate), else the first matrix-free one. ``n`` counts the
    unknowns: the bonds times their tangential ``components``.
    """
    law = _law(slip_law)
    k = len(TANGENTIAL_MODELS.get(components, ("x",)))
    cands = [METHODS.get(m) for m in METHODS.names()]
    cands = [m for m in cands if m.auto and m.exact and m.runs(law, components)]
    if not cands:
        if components != "x":
            raise _no_vector(law, components)
        raise InputError(f"slip_law = {law.name!r} has no exact decoupled pull method; use "
                         "the coupled model (coupling.enabled = true, or couple())")
    dense = [m for m in cands if m.dense]
    free = [m for m in cands if not m.dense and not m.tiny]
    if dense and not free:
        return dense[0].name
    memory = available_bytes() if memory is None else memory
    for m in free:  # above is a bond count (measured per bond, as fast for the vector)
        if (m.above and not law.needs and n >= m.above * k
                and _fits(m, n, law, precision, memory, k, components)):
            return m.name
    if precision == "single":
        for m in dense:
            if single_ok(law, m, components):
                return m.name  # asked for by name: it checks its memory itself
    for m in cands:
        if n <= m.tiny:
            return m.name
    limit = lapack64.max_n()
    for m in dense:
        if _fits(m, n, law, precision, memory, k, components) and (limit is None
                                                                   or n <= limit):
            return m.name
    fits = [m for m in free
            if m.solver is None or _fits(m, n, law, precision, memory, k, components)]
    return (fits or free or dense)[0].name


def pull(
    normal: NormalResult,
    *,
    lam: float = 0.2,
    slip_law: str = "break",
    method: str = "auto",
    tol: float = 1e-10,
    early_stop: bool = True,
    batch_size: int = 16,
    block: int = 128,
    max_iter: int = 10_000,
    threads: int | None = None,
    estimate_error: bool = False,
    lam_dynamic: float | None = None,
    slip_distance: float | None = None,
    precision: str = "auto",
    components: str = "x",
    direction: float = 0.0,
    facets: int = FACETS,
) -> PullResult:
    r"""Pull a squeezed contact sideways until it slides (docs/theory/pull.rst#break-law).

    Parameters
    ----------
    normal : NormalResult
        The squeeze result; its contact sites (``f_z > 0``) are the initial bonds, and its
        problem (grid, material, operator) defines :math:`G_{xx}`.
    lam : float
        Local friction coefficient :math:`\lambda > 0`: a bond breaks (or slips) when
        :math:`|f_x| > \lambda f_z`.
    slip_law : {"break", "coulomb", "slip-weakening"}
        ``"break"``: a broken bond carries no force (the report). ``"coulomb"``: a slipping
        site carries :math:`\lambda f_z`. ``"slip-weakening"``: a slipping site's strength
        falls from :math:`\lambda f_z` to ``lam_dynamic`` :math:`f_z` over the slip
        ``slip_distance`` (:mod:`roughslip.friction.weakening`).
    method : str
        A name from :data:`METHODS`: ``"auto"``, ``"literal"``, ``"inverse"``, ``"cg"`` or
        ``"batch"`` (module docstring). ``"auto"`` picks an exact method by bond count and
        memory (:func:`choose_method`).
    tol : float
        Relative residual of the tangential solves (and of the certification of ``inverse``).
    early_stop : bool
        Stop once no later state can exceed the best force (exact): under the break law
        once :math:`\lambda\sum_S f_z` falls below the best :math:`F_{x,\rm lim}`, under
        slip-weakening once the bonds' strengths sum to no more than it.
        ``method="literal"`` always runs to the last bond, as the report does.
    batch_size : int
        Bonds broken per solve by ``method="batch"``.
    block : int
        Removals per blocked update of ``method="inverse"``.
    threads : int, optional
        BLAS threads of the dense methods (default: the problem's threads).
    estimate_error : bool
        Also estimate the error of the friction force (``details.error_estimate``: the
        pull's own part by :func:`refinement_estimate`, one CG solve on the peak state, and
        the squeeze's part by :func:`normal_share`, one CG solve on the contact set) and the
        condition number of :math:`G_{xx}` on the bonds (``details.condition``,
        :func:`bond_spectrum`, a few hundred operator applications; deterministic) with the
        bound estimate ``details.error_bound`` :math:`= \hat\kappa\rho`. Both are estimates
        (docs/methods.rst#estimates-against-truth compares them with the true error). The
        ``"batch"`` method and the slip-weakening law have no ``error_estimate`` (NaN): the
        refinement estimate assumes the break law's peak state.
    lam_dynamic, slip_distance : float, optional
        The residual coefficient :math:`\lambda_d \in [0, \lambda]` and the slip
        :math:`d_c > 0` over which the strength falls to it; ``slip_law="slip-weakening"``
        only, and needed there.
    precision : {"auto", "double", "single"}
        The precision of the stored matrix of the ``"inverse"`` and ``"hierarchical"``
        methods. ``"single"`` (the break law; the Coulomb law in the x-only model) stores it
        in float32, half the memory, and keeps the events and the friction force exact by
        certified decisions (:mod:`roughslip.friction.breaking_single`,
        :mod:`roughslip.friction.sliding_single`). ``"auto"``: double when the matrix
        fits in the memory available, else single (:func:`choose_precision`; for
        ``"hierarchical"`` by its estimate). The other methods take ``"auto"`` only.
    components : {"x", "xy"}
        The tangential model (:data:`~roughslip.friction.bonds.TANGENTIAL_MODELS`): ``"x"``,
        the report's, each bond carries :math:`f_x` alone and :math:`u_y` is free; ``"xy"``,
        each bond carries the traction vector :math:`(f_x, f_y)` and sticks in both
        directions, coupled through :math:`G_{xy}` (docs/theory/pull.rst#traction-vector):
        at :math:`\nu = 0` every law and method, the x-only model turned (:func:`turned`);
        at :math:`\nu > 0` the break law, :math:`|\mathbf f_t| > \lambda f_z`, on the
        dense and the compressed inverse in either precision, and the Coulomb law's cone on
        the dense inverse (``facets``).
    direction : float
        The drive's angle in the surface plane, degrees from x toward y; only 0 in the
        ``"x"`` model. The curve is the pull force along the drive
        (``friction_force``), and :attr:`~roughslip.friction.result.PullResult.friction_vector`
        the force vector of the peak.
    facets : int
        The Coulomb law with ``components = "xy"`` at :math:`\nu > 0`: the facets of the
        regular polygon inscribed in the cone :math:`|\mathbf f_t| \le \lambda f_z`, one
        vertex on the drive (docs/theory/pull.rst#coulomb-cone; at least 4). Its strength is
        the cone's within :math:`1 - \cos(\pi/\mathrm{facets})` in every direction.

    Returns
    -------
    PullResult
        The curve from the start, the peak, and the diagnostics; the error estimates are in
        its :class:`~roughslip.friction.result.DecoupledDetails`.
    """
    t0 = time.perf_counter()
    check_friction(lam, slip_law)
    law = _law(slip_law).bind(lam, lam_dynamic=lam_dynamic, slip_distance=slip_distance)
    asked = _method(method)
    if precision not in PRECISIONS:
        raise InputError(f"precision = {precision!r}: must be one of {', '.join(PRECISIONS)}")
    if not 0 < tol < 1:
        raise InputError(f"tol = {tol!r}: must satisfy 0 < tol < 1")
    if int(batch_size) < 1 or int(block) < 1:
        raise InputError("batch_size and block must be >= 1")
    threads = normal.problem.threads if threads is None else int(threads)
    if threads < 1:
        raise InputError(f"threads = {threads!r}: must be >= 1")
    comps, direction = check_direction(components, direction)
    if isinstance(facets, bool) or not isinstance(facets, int | np.integer) or not (
            MIN_FACETS <= facets <= MAX_FACETS):
        raise InputError(f"pull.facets = {facets!r}: must be an integer from {MIN_FACETS} "
                         f"to {MAX_FACETS}")
    if len(comps) > 1 and normal.problem.material.nu != 0 and estimate_error:
        raise InputError(f"pull.error_estimate: the error estimate is the x-only model's; it "
                         f"has none for pull.components = {components!r} at nu > 0")
    if len(comps) > 1 and normal.problem.material.nu == 0:
        # the isotropic half-space: the x-only model along the drive, turned (exact)
        return turned(pull(normal, lam=lam, slip_law=slip_law, method=method, tol=tol,
                           early_stop=early_stop, batch_size=batch_size, block=block,
                           max_iter=max_iter, threads=threads, estimate_error=estimate_error,
                           lam_dynamic=lam_dynamic, slip_distance=slip_distance,
                           precision=precision), components, direction)
    opt = PullOptions(tol=float(tol), early_stop=bool(early_stop), batch_size=int(batch_size),
                      block=int(block), max_iter=int(max_iter), threads=threads, law=law,
                      method=asked, facets=int(facets))
    n = Bonds.count(normal)
    if n == 0:
        return BreakCurve(Bonds(normal, float(lam), components=comps, direction=direction),
                          early_stop).result(t0, asked.name, converged=True,
                                             message="no contact: nothing to pull",
                                             slip_law=law.name)
    impl = (METHODS.get(choose_method(n * len(comps), slip_law=law, precision=precision,
                                      components=components))
            if asked.chooses else asked)
    if not impl.runs(law, components):
        if components not in law.components:
            raise _no_vector(law, components)
        if components != "x" and impl.runs(law):
            raise InputError(f"pull.components = {components!r}: method {impl.name!r} runs "
                             f"slip_law = {law.name!r} in the x-only model only; use method "
                             f"{', '.join(repr(m) for m in methods_for(law, components))}")
        raise InputError(f"slip_law = {law.name!r} supports methods "
                         f"{', '.join(methods_for(law, components))}, not {impl.name!r}")
    if precision == "auto":
        precision = (choose_precision(n * len(comps), slip_law=law, block=int(block),
                                      method=impl, per_point=len(comps),
                                      components=components)
                     if impl.solver is not None else "double")
    if precision == "single" and not single_ok(law, impl, components):
        laws = ", ".join(repr(n) for n in LAWS.names() if components in LAWS.get(n).single)
        methods = ", ".join(repr(n) for n in METHODS.names()
                            if "single" in METHODS.get(n).precisions)
        raise InputError(f"precision = 'single': only slip_law {laws} with method {methods} "
                         f"has it (certified decisions on a single-precision matrix), not "
                         f"slip_law = {law.name!r} with method {impl.name!r}")
    opt = replace(opt, precision=precision, method=impl)
    run = impl.run if impl.solver is None else law.engine
    # Dense and compressed linear algebra gets the threads, and the certification's FFTs run
    # on one thread beside it; FFT-bound CG loops keep BLAS single-threaded (competing FFTW
    # and OpenBLAS thread pools made CG iterations 60x slower).
    blas = impl.blas or impl.dense
    b = Bonds(normal, float(lam), threads=1 if blas else None, components=comps,
              direction=direction)
    with blas_threads(threads if blas else 1):
        res = run(b, opt, t0)
    if impl is not asked:
        res = replace(res, message=f"auto chose {impl.name} for {n} bonds; " + res.message)
    if estimate_error:
        lo, hi = bond_spectrum(normal, threads=threads)
        kappa = hi / lo
        res = replace(res, details=replace(res.details, condition=kappa,
                                           error_bound=kappa * res.residual),
                      seconds=time.perf_counter() - t0)
        if impl.estimate and not law.lands:  # batch and slip-weakening: none (NaN)
            # a sliding law's friction force takes no tangential solve
            solve = 0.0 if law.slides else refinement_estimate(normal, res)
            part = abs(normal_share(normal, res))
            res = replace(res, details=replace(res.details, error_estimate=solve + part,
                                               solve_error_estimate=solve,
                                               normal_error_estimate=part),
                          seconds=time.perf_counter() - t0,
                          message=f"{res.message}; estimated error {solve + part:.2e} "
                                  f"(solves {solve:.1e}, normal forces {part:.1e})")
    return res


#: bonds from which ``auto`` takes the compressed inverse: on the rough benchmark scenes (20 %
#: contact, 2 cores) it took 2.3 times the dense double inverse's time at 3 275 bonds, 1.20 at
#: 7 362, 0.94 at 10 025 and 0.71 at 13 074 (docs/benchmarks.md)
HIERARCHICAL_ABOVE = 10_000

METHODS.register("auto", "an exact method chosen by bond count and memory")(
    PullMethod("auto", exact=True, dense=False, auto=False, chooses=True))
METHODS.register("literal", "the report's algorithm, one CG solve from zero per break")(
    PullMethod("literal", exact=True, dense=False, run=break_literal, tiny=12,
               early_stop=False))
METHODS.register("inverse", "exact, an updated inverse of G_xx on the bonds (O(n^2) memory)")(
    PullMethod("inverse", exact=True, dense=True, solver=UpdatableInverse,
               offers=frozenset(CAPABILITIES), precisions=("double", "single"),
               components=("x", "xy")))
METHODS.register("hierarchical", "exact with certified decisions, a compressed (HODLR) inverse "
                 "of G_xx on the bonds (a fraction of the dense memory)")(
    PullMethod("hierarchical", exact=True, dense=False, blas=True,
               solver=HierarchicalInverse, offers=frozenset(CAPABILITIES),
               precisions=("double", "single"), inexact=True, above=HIERARCHICAL_ABOVE,
               components=("x", "xy")))
METHODS.register("cg", "exact and matrix-free, a warm-started CG solve per break")(
    PullMethod("cg", exact=True, dense=False, run=break_cg))
METHODS.register("batch", "approximate, several bonds broken per solve")(
    PullMethod("batch", exact=False, dense=False, run=break_batch, estimate=False))
