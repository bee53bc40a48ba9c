r"""The decoupled Coulomb pull: a bond whose :math:`|f_x|` reaches :math:`\lambda f_z` slips,
carrying :math:`f_x = \pm\lambda f_z` (docs/theory/pull.rst; for a Hertz contact this is
Cattaneo–Mindlin, docs/methods.rst#cattaneo-mindlin).
"""

from __future__ import annotations

import math
import time

import numpy as np

from roughslip.contact.bonds import (
    BondRows,
    Bonds,
    PullOptions,
    SlipResult,
    _no_new,
    bond_inverse,
    certify,
    track,
)
from roughslip.errors import NumericalError
from roughslip.linalg.inverse import Tracked


def _coulomb(b: Bonds, opt: PullOptions, t0: float) -> SlipResult:
    r"""Event-driven Coulomb slip: the exact piecewise-linear :math:`F_x(D_x)` to full sliding.

    With stick set :math:`S` and slip set :math:`L` carrying :math:`f_x = s\,\lambda f_z`
    (:math:`s = \pm 1`, monotonic loading, no re-sticking), the stick forces are
    :math:`f_S = D\,\varphi - \psi` with :math:`\varphi = G_{SS}^{-1}1` and
    :math:`\psi = G_{SS}^{-1}G_{SL}f_L`. The next stick site to reach :math:`\pm\lambda f_z`
    slips; if that happens below the current :math:`D` it slips at once (an avalanche). When
    site :math:`k` moves to :math:`L`, :math:`\varphi \leftarrow \varphi - c\varphi_k/c_k`
    and :math:`\psi \leftarrow \psi - c(\psi_k + s_k\lambda f_{z,k})/c_k`
    (:func:`~roughslip.contact.bonds.bond_inverse`). Both are certified against the FFT
    operator after each block.
    """
    n, tol = b.n, opt.tol
    inv = bond_inverse(b, opt.block, opt.threads)
    track(inv, "phi", np.ones(n))
    inv.tracked["psi"] = Tracked(np.zeros(n), np.zeros(n), _no_new)
    rows = BondRows(b)
    sign = np.zeros(n)  # slip direction per bond position
    dx, fx, sites = [], [], []
    D, slip_sum = 0.0, 0.0
    worst, refinements, ok = 0.0, 0, True
    while rows.alive:
        phi, psi = inv.tracked["phi"].x, inv.tracked["psi"].x
        cap, pos = rows.cap, inv.ids
        with np.errstate(divide="ignore", invalid="ignore"):
            d_pos = np.where(phi > 0, (cap + psi) / phi, np.inf)
            d_neg = np.where(phi < 0, (psi - cap) / phi, np.inf)
        d_pos[~np.isfinite(cap)] = np.inf
        d_neg[~np.isfinite(cap)] = np.inf
        dk = np.minimum(d_pos, d_neg)
        k = int(np.argmin(dk))
        if not math.isfinite(float(dk[k])):
            raise NumericalError("Coulomb pull: no stick site can reach its bound")
        D = max(D, float(dk[k]))
        s_k = 1.0 if d_pos[k] <= d_neg[k] else -1.0
        F = D * float(phi.sum()) - float(psi.sum()) + slip_sum
        dx.append(D)
        fx.append(F)
        sites.append(int(b.sites[pos[k]]))
        capk = float(cap[k])
        sign[pos[k]] = s_k
        slip_sum += s_k * capk
        if rows.alive == 1:
            break
        # the bond's slip force joins the load: psi <- psi - c (psi_k + s_k cap_k) / c_k,
        # which the removal does for the tracked psi with psi_k so raised
        psi[k] += s_k * capk
        rows.remove(inv, k)
        if rows.fold(inv):
            r1, n1 = certify(b, inv, "phi", None, tol)
            r2, n2 = certify(b, inv, "psi", b.field(sign * b.cap), tol)
            worst, refinements = max(worst, r1, r2), refinements + n1 + n2
            ok &= max(r1, r2) <= tol
    total = float((sign * b.cap).sum())
    return SlipResult(
        friction_force=total, peak_index=len(fx) - 1, dx_lim=np.array(dx),
        fx_lim=np.array(fx), broken_site=np.array(sites, dtype=np.int64),
        stick_at_peak=np.zeros(b.shape, bool), fx_at_peak=b.field(sign * b.cap),
        converged=bool(ok), seconds=time.perf_counter() - t0, method="inverse",
        slip_law="coulomb", lam=b.lam, n_bonds=n, steps=len(fx), residual=worst,
        solves=refinements, normal_force=b.normal.normal_force,
        message="exact event sequence to full sliding",
    )
