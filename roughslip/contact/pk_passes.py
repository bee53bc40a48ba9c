r"""The element-wise passes of the Polonsky–Keer iteration
(:class:`~roughslip.contact.squeeze.PolonskyKeer`), fused.

One iteration of the constrained conjugate gradients reads and writes the whole grid about
twenty times outside its one convolution: the gap, the contact mask, the gap on contact and
its extremes, the search direction, the updates of the forces and of the displacement, the
clipping of negative forces and the search for overlap off contact. With numpy each is a pass
of its own; on the periodic grid, whose transforms are four times smaller than the open
grid's, they cost as much as the FFTs (docs/benchmarks.md).

Here they are four passes (:func:`gap`, :func:`direction`, :func:`step`, and under load
control :func:`shift_gap`) and the load-control rescale (:func:`scale`), compiled with numba
when it is installed, else the same operations in numpy.
Both paths perform the same IEEE operations in the same order on every element, and the
reductions that are not exact (sums and dot products) stay with numpy in the caller, so the
two give bitwise the same iterates (tested). Extremes and counts are exact in any order.
``ROUGHSLIP_FUSED=0`` in the environment selects the numpy path.
"""

from __future__ import annotations

import functools
from types import SimpleNamespace

import numpy as np

from roughslip.linalg import jit

#: whether numba is installed (it is imported, and the passes compiled, at their first use:
#: compiled once per installation, then loaded from numba's cache)
HAVE_NUMBA = jit.HAVE_NUMBA
#: whether the passes run compiled (numba installed and ``ROUGHSLIP_FUSED`` not ``0``)
FUSED = jit.ENABLED

# ------------------------------------------------------------------------------------------------
# numpy: the reference path
# ------------------------------------------------------------------------------------------------
def _gap_np(u, ubar, p, g, Sf, gs, off):
    np.subtract(u, ubar, out=g)
    np.sign(p, out=Sf)  # p >= 0: the contact mask as 0.0 / 1.0
    np.multiply(g, Sf, out=gs)
    np.subtract(g, gs, out=off)
    return int(np.count_nonzero(Sf))


def _shift_gap_np(g, Sf, gs, off, shift):
    np.subtract(g, shift, out=g)
    np.multiply(g, Sf, out=gs)
    np.subtract(g, gs, out=off)


def _direction_np(t, beta, Sf, gs):
    np.multiply(t, beta, out=t)
    np.multiply(t, Sf, out=t)
    np.add(t, gs, out=t)


def _step_np(p, t, u, r, g, Sf, tau):
    np.subtract(p, t * tau, out=p)
    np.subtract(u, r * tau, out=u)
    return np.flatnonzero(p < 0.0), np.flatnonzero((Sf == 0.0) & (g < 0.0))


def _scale_np(p, u, s):
    p *= s
    u *= s


# ------------------------------------------------------------------------------------------------
# numba: the same operations, one loop each and without branches (the contact set is ragged,
# so branches mispredict)
# ------------------------------------------------------------------------------------------------
@functools.cache
def _compiled() -> SimpleNamespace:
    """The numba kernels, defined and compiled (or loaded from the cache) at the first call."""
    _jit = jit.njit()

    @_jit
    def _gap_nb(u, ubar, p, g, Sf, gs, off):
        u, ubar, p = u.ravel(), ubar.ravel(), p.ravel()
        g, Sf, gs, off = g.ravel(), Sf.ravel(), gs.ravel(), off.ravel()
        n_s = 0
        for i in range(u.size):
            gi = u[i] - ubar[i]
            pi = p[i]
            s = 1.0 if pi > 0.0 else (-1.0 if pi < 0.0 else (0.0 if pi == 0.0 else pi))
            gsi = gi * s
            g[i] = gi
            Sf[i] = s
            gs[i] = gsi
            off[i] = gi - gsi
            n_s += s != 0.0
        return n_s

    @_jit
    def _shift_gap_nb(g, Sf, gs, off, shift):
        g, Sf, gs, off = g.ravel(), Sf.ravel(), gs.ravel(), off.ravel()
        for i in range(g.size):
            gi = g[i] - shift
            gsi = gi * Sf[i]
            g[i] = gi
            gs[i] = gsi
            off[i] = gi - gsi

    @_jit
    def _direction_nb(t, beta, Sf, gs):
        t, Sf, gs = t.ravel(), Sf.ravel(), gs.ravel()
        for i in range(t.size):
            t[i] = t[i] * beta * Sf[i] + gs[i]

    @_jit
    def _step_nb(p, t, u, r, g, Sf, tau, flags):
        p, t, u, r = p.ravel(), t.ravel(), u.ravel(), r.ravel()
        g, Sf = g.ravel(), Sf.ravel()
        n_clip, n_enter = 0, 0
        for i in range(p.size):
            pi = p[i] - t[i] * tau
            p[i] = pi
            u[i] = u[i] - r[i] * tau
            c = pi < 0.0
            e = (Sf[i] == 0.0) & (g[i] < 0.0)
            flags[i] = c + 2 * e
            n_clip += c
            n_enter += e
        return n_clip, n_enter

    @_jit
    def _collect_nb(flags, n_clip, n_enter):
        # few sites change: skip the flags eight at a time while they are all zero
        out = np.empty(n_clip + n_enter, np.int64)
        a, b = 0, n_clip + n_enter - 1
        whole = flags.size // 8
        words = flags[: 8 * whole].view(np.uint64)
        for w in range(whole + 1):
            if w < whole and words[w] == 0:
                continue
            for i in range(8 * w, min(8 * w + 8, flags.size)):
                f = flags[i]
                if f == 1:
                    out[a] = i
                    a += 1
                elif f == 2:
                    out[b] = i
                    b -= 1
        return out

    @_jit
    def _scale_nb(p, u, s):
        p, u = p.ravel(), u.ravel()
        for i in range(p.size):
            p[i] = p[i] * s
            u[i] = u[i] * s

    return SimpleNamespace(gap=_gap_nb, shift_gap=_shift_gap_nb, direction=_direction_nb,
                           step=_step_nb, collect=_collect_nb, scale=_scale_nb)


# ------------------------------------------------------------------------------------------------
# the passes
# ------------------------------------------------------------------------------------------------
def _pick(fused: bool | None) -> SimpleNamespace | None:
    """The compiled kernels when they are to be used, else None (the numpy path)."""
    if HAVE_NUMBA and (FUSED if fused is None else fused):
        return _compiled()
    return None


def _extremes(gs: np.ndarray, off: np.ndarray) -> tuple[float, float, float]:
    return float(gs.max()), float(gs.min()), float(off.min())


def gap(u: np.ndarray, ubar: np.ndarray, p: np.ndarray, g: np.ndarray, Sf: np.ndarray,
        gs: np.ndarray, off: np.ndarray, fused: bool | None = None
        ) -> tuple[int, float, float, float]:
    r"""The gap :math:`g = u - \bar u`, the contact mask :math:`S = \mathrm{sign}(p)` (0.0 or
    1.0, since :math:`p \ge 0`), the gap on contact :math:`g_S = g\,S` and off it,
    :math:`g - g_S`, written into ``g``, ``Sf``, ``gs`` and ``off``. Returns the number of
    contact sites, :math:`\max g_S`, :math:`\min g_S` and the least gap off contact (NaN if
    any value is NaN). ``fused``: force the compiled (True) or numpy (False) path."""
    if nb := _pick(fused):
        n_s = int(nb.gap(u, ubar, p, g, Sf, gs, off))
    else:
        n_s = _gap_np(u, ubar, p, g, Sf, gs, off)
    return (n_s, *_extremes(gs, off))


def shift_gap(g: np.ndarray, Sf: np.ndarray, gs: np.ndarray, off: np.ndarray, shift: float,
              fused: bool | None = None) -> tuple[float, float, float]:
    r"""Under load control: :math:`g \leftarrow g - \delta` for the approach :math:`\delta`
    (``shift``), and ``gs`` and ``off`` again; returns the extremes as :func:`gap` does."""
    if nb := _pick(fused):
        nb.shift_gap(g, Sf, gs, off, float(shift))
    else:
        _shift_gap_np(g, Sf, gs, off, shift)
    return _extremes(gs, off)


def direction(t: np.ndarray, beta: float, Sf: np.ndarray, gs: np.ndarray,
              fused: bool | None = None) -> None:
    r"""The conjugate search direction in place: :math:`t \leftarrow (\beta t)\,S + g_S`."""
    if nb := _pick(fused):
        nb.direction(t, float(beta), Sf, gs)
    else:
        _direction_np(t, beta, Sf, gs)


_NONE = np.zeros(0, dtype=np.int64)  # no site changed (never written to)


def step(p: np.ndarray, t: np.ndarray, u: np.ndarray, r: np.ndarray, g: np.ndarray,
         Sf: np.ndarray, tau: float, flags: np.ndarray, fused: bool | None = None
         ) -> tuple[np.ndarray, np.ndarray]:
    r"""The step :math:`p \leftarrow p - \tau t`, :math:`u \leftarrow u - \tau r` in place;
    returns the flat indices, ascending, of the sites whose new force is negative and of the
    sites that were off contact (``Sf == 0``) with a negative gap ``g``. The two sets are
    disjoint (a site off contact has :math:`t = 0`). ``flags``: int8 work space of the grid's
    size. Nothing is clipped here: the caller projects the sites."""
    if nb := _pick(fused):
        flat = flags.ravel()
        n_clip, n_enter = nb.step(p, t, u, r, g, Sf, float(tau), flat)
        if not (n_clip or n_enter):
            return _NONE, _NONE
        out = nb.collect(flat, n_clip, n_enter)
        return out[:n_clip], out[n_clip:][::-1]
    return _step_np(p, t, u, r, g, Sf, tau)


def scale(p: np.ndarray, u: np.ndarray, s: float, fused: bool | None = None) -> None:
    """``p *= s`` and ``u *= s`` in place (load control's rescaling to the force)."""
    if nb := _pick(fused):
        nb.scale(p, u, float(s))
    else:
        _scale_np(p, u, s)
