"""Where a beam touches seed 000's body, and how far it is deflected (Eq. 4-5).

Contact (Xuan, Wang & Li, ``/work/shared/seeds/000_*.txt``, Eq. 4-5) is frictionless, along
the ellipsoid normal; the deflection angle is the smallest rotation of the plate about its
hinge that keeps the whole plate (finite length and width) out of the body; the force
magnitude follows from the beam's torque balance. In the dynamics the plate keeps contact
and cannot pass through the body: one trapped under it slides along the underside until its
tip clears the tail, rather than jumping upright as soon as the upright position is clear
(the landscape keeps the smallest angle).

Two implementations live here: a scalar one (Newton from the previous step's angle, fast
enough for 0.2 ms steps in pure Python; ``contact``, ``deflection_angle``) and a numpy one
(bracketing bisection over whole arrays, for the landscape and the estimator;
``deflection_angles``, ``unit_contact_forces``). Both are tested against a brute-force
search. Poses are (x, roll, pitch) with R = Ry(pitch) Rx(roll), as in hil/world/beams.py.
"""
from __future__ import annotations

import math

import numpy as np

from hexhil.hil.world.beam_body import PAPER_BODY, BodyGeometry

THETA_MAX_RAD = math.pi / 2  # plate flat on the ground: it cannot be pushed further
_LEVER_MIN_M = 1e-3         # contact at the hinge line: keep the force finite


# ----------------------------------------------------------------------------- scalar geometry
def _box_min(q0x, q0y, q0z, ux, uy, uz, vx, vy, vz, L, w):
    """min |q0 + s U + t V|^2 over s in [0, L], t in [0, w]: returns (f, s, t)."""
    uu = ux * ux + uy * uy + uz * uz
    vv = vx * vx + vy * vy + vz * vz
    uv = ux * vx + uy * vy + uz * vz
    gu = q0x * ux + q0y * uy + q0z * uz
    gv = q0x * vx + q0y * vy + q0z * vz
    qq = q0x * q0x + q0y * q0y + q0z * q0z
    det = uu * vv - uv * uv
    s = (uv * gv - vv * gu) / det
    t = (uv * gu - uu * gv) / det
    if 0.0 <= s <= L and 0.0 <= t <= w:
        return qq + s * gu + t * gv, s, t
    best = None
    for s_fix in (0.0, L):
        tt = -(gv + s_fix * uv) / vv
        tt = 0.0 if tt < 0.0 else (w if tt > w else tt)
        f = qq + 2 * s_fix * gu + 2 * tt * gv + s_fix * s_fix * uu + 2 * s_fix * tt * uv + tt * tt * vv
        if best is None or f < best[0]:
            best = (f, s_fix, tt)
    for t_fix in (0.0, w):
        ss = -(gu + t_fix * uv) / uu
        ss = 0.0 if ss < 0.0 else (L if ss > L else ss)
        f = qq + 2 * ss * gu + 2 * t_fix * gv + ss * ss * uu + 2 * ss * t_fix * uv + t_fix * t_fix * vv
        if f < best[0]:
            best = (f, ss, t_fix)
    return best


class _PlateFrame:
    """One beam seen from the body's normalised frame (ellipsoid -> unit sphere) at one pose."""

    __slots__ = ("q0", "v", "sa", "ca", "beta", "ia", "ib", "ic", "L", "w")

    def __init__(self, g: BodyGeometry, x_m: float, roll: float, pitch: float, hb_m: float,
                 beam: int) -> None:
        sa, ca, sb, cb = math.sin(roll), math.cos(roll), math.sin(pitch), math.cos(pitch)
        y_lo, _ = g.beam_y_range(beam)
        dx, dy, dz = -x_m, y_lo, hb_m - g.height_m      # hinge corner relative to the centre
        self.ia, self.ib, self.ic = 1.0 / g.a_m, 1.0 / g.b_m, 1.0 / g.c_m
        # body axes in the world: e1 = (cb, 0, -sb), e2 = (sb sa, ca, cb sa), e3 = (sb ca, -sa, cb ca)
        self.q0 = ((cb * dx - sb * dz) * self.ia,
                   (sb * sa * dx + ca * dy + cb * sa * dz) * self.ib,
                   (sb * ca * dx - sa * dy + cb * ca * dz) * self.ic)
        self.v = (0.0, ca * self.ib, -sa * self.ic)
        self.sa, self.ca, self.beta = sa, ca, pitch
        self.L, self.w = g.beam_length_m, g.beam_width_m

    def f(self, theta: float):
        """(min normalised distance^2 of the plate at theta, s, t, d f / d theta)."""
        phi = theta - self.beta
        sp, cp = math.sin(phi), math.cos(phi)
        ux, uy, uz = sp * self.ia, self.sa * cp * self.ib, self.ca * cp * self.ic
        q0x, q0y, q0z = self.q0
        vx, vy, vz = self.v
        f, s, t = _box_min(q0x, q0y, q0z, ux, uy, uz, vx, vy, vz, self.L, self.w)
        qx, qy, qz = q0x + s * ux + t * vx, q0y + s * uy + t * vy, q0z + s * uz + t * vz
        df = 2.0 * s * (qx * cp * self.ia - qy * self.sa * sp * self.ib - qz * self.ca * sp * self.ic)
        return f, s, t, df


def _solve_theta(pf: _PlateFrame, theta_prev: float) -> tuple[float, float, float]:
    """The plate's deflection (rad) and contact point (s, t) on it, given its deflection one step
    earlier; theta 0 means no contact.

    A massless plate keeps contact with the body (Sec. II-A) and cannot pass through it: from
    its previous angle it is pushed forward to the first clear angle above it, or springs back
    to the first contact below it (0 if nothing stops it). From 0 that is the smallest clear
    angle, the landscape's definition; they differ for a plate trapped under the body once its
    upright position is already clear: it slides along the underside instead of jumping back
    through the body. Newton from the previous angle (one or two evaluations per 0.2 ms step),
    falling back to a scan from it and bisection.
    """
    if theta_prev <= 0.0:
        f0, s0, t0, _ = pf.f(0.0)
        if f0 >= 1.0:
            return 0.0, s0, t0
        return _bracket_theta(pf, 0.0, up=True)
    up = pf.f(theta_prev)[0] < 1.0          # the body has moved into the plate: pushed forward
    sign = 1.0 if up else -1.0
    th = theta_prev
    for _ in range(8):
        f, s, t, df = pf.f(th)
        if abs(f - 1.0) < 1e-12:
            return th, s, t
        if df <= 1e-12:
            break
        nxt = th - (f - 1.0) / df
        if not 0.0 < nxt < THETA_MAX_RAD or abs(nxt - theta_prev) > 0.05 or sign * (nxt - theta_prev) < 0.0:
            break
        th = nxt
    return _bracket_theta(pf, theta_prev, up)


def _bracket_theta(pf: _PlateFrame, theta_from: float = 0.0, up: bool = True) -> tuple[float, float, float]:
    """From ``theta_from``, the first clear angle above it (``up``) or the first contact below it
    (else; 0 when there is none): a scan in steps of pi/128, then bisection (the robust path)."""
    step = THETA_MAX_RAD / 64
    lo = hi = theta_from
    while True:
        nxt = min(hi + step, THETA_MAX_RAD) if up else max(lo - step, 0.0)
        clear = pf.f(nxt)[0] >= 1.0
        if up:
            lo, hi = hi, nxt
            if clear:
                break
            if nxt >= THETA_MAX_RAD:         # even the flat plate is inside the body
                _, s, t, _ = pf.f(THETA_MAX_RAD)
                return THETA_MAX_RAD, s, t
        else:
            lo, hi = nxt, lo
            if not clear:
                break
            if nxt <= 0.0:                   # nothing below: the plate springs upright, no contact
                _, s, t, _ = pf.f(0.0)
                return 0.0, s, t
    for _ in range(40):                      # lo inside the body, hi clear
        mid = 0.5 * (lo + hi)
        if pf.f(mid)[0] >= 1.0:
            hi = mid
        else:
            lo = mid
        if hi - lo < 1e-12:
            break
    _, s, t, _ = pf.f(hi)
    return hi, s, t


def deflection_angle(x_m: float, roll_rad: float, pitch_rad: float, hb_m: float, beam: int,
                     geometry: BodyGeometry = PAPER_BODY) -> float:
    """Exact deflection of one beam (rad) for one body pose (scalar reference)."""
    pf = _PlateFrame(geometry, x_m, roll_rad, pitch_rad, hb_m, beam)
    return _bracket_theta(pf)[0] if pf.f(0.0)[0] < 1.0 else 0.0


def _surface_normal(g: BodyGeometry, rx, ry, rz, sa, ca, sb, cb):
    """Outward Eq. 5 normal (x/a^2, y/b^2, z/c^2), not normalised, at the world-frame point
    (rx, ry, rz) relative to the centre, for roll/pitch sines and cosines; floats or arrays."""
    bx = cb * rx - sb * rz  # the point in the body frame
    by = sb * sa * rx + ca * ry + cb * sa * rz
    bz = sb * ca * rx - sa * ry + cb * ca * rz
    nx_b, ny_b, nz_b = bx / g.a_m ** 2, by / g.b_m ** 2, bz / g.c_m ** 2
    return (cb * nx_b + sb * sa * ny_b + sb * ca * nz_b,  # back to the world
            ca * ny_b - sa * nz_b,
            -sb * nx_b + cb * sa * ny_b + cb * ca * nz_b)


def contact(g: BodyGeometry, x_m: float, roll: float, pitch: float, hb_m: float, beam: int,
            theta_prev: float):
    """(theta, contact point relative to the centre (world), unit inward force direction, lever)."""
    pf = _PlateFrame(g, x_m, roll, pitch, hb_m, beam)
    th, s, t = _solve_theta(pf, theta_prev)
    if th == 0.0:
        return 0.0, None, None, 0.0
    st, ct = math.sin(th), math.cos(th)
    y_lo, _ = g.beam_y_range(beam)
    rx, ry, rz = s * st - x_m, y_lo + t, hb_m + s * ct - g.height_m
    nx, ny, nz = _surface_normal(g, rx, ry, rz, math.sin(roll), math.cos(roll),
                                 math.sin(pitch), math.cos(pitch))
    norm = math.sqrt(nx * nx + ny * ny + nz * nz)
    nx, ny, nz = nx / norm, ny / norm, nz / norm
    lever = s * (ct * nx - st * nz)      # (s u x n) . e_y: the beam's moment arm (Eq. 4)
    return th, (rx, ry, rz), (-nx, -ny, -nz), max(lever, _LEVER_MIN_M)


# ----------------------------------------------------------------------------- vectorised
def _box_min_np(q0, U, V, L, w):
    """Vectorised :func:`_box_min`; q0, U, V are (3, ...) arrays. Returns (f, s, t)."""
    uu = (U * U).sum(0)
    vv = (V * V).sum(0)
    uv = (U * V).sum(0)
    gu = (q0 * U).sum(0)
    gv = (q0 * V).sum(0)
    qq = (q0 * q0).sum(0)
    det = uu * vv - uv * uv

    def fval(s, t):
        return qq + 2 * s * gu + 2 * t * gv + s * s * uu + 2 * s * t * uv + t * t * vv

    s_in = (uv * gv - vv * gu) / det
    t_in = (uv * gu - uu * gv) / det
    inside = (s_in >= 0) & (s_in <= L) & (t_in >= 0) & (t_in <= w)
    best_f = np.where(inside, fval(s_in, t_in), np.inf)
    best_s = np.where(inside, s_in, 0.0)
    best_t = np.where(inside, t_in, 0.0)
    # the four edges: s or t held at a bound, the other at its clipped optimum
    edges = [(np.full_like(gu, s_fix), np.clip(-(gv + s_fix * uv) / vv, 0.0, w)) for s_fix in (0.0, L)]
    edges += [(np.clip(-(gu + t_fix * uv) / uu, 0.0, L), np.full_like(gu, t_fix)) for t_fix in (0.0, w)]
    for ss, tt in edges:
        f = fval(ss, tt)
        better = f < best_f
        best_f, best_s, best_t = np.where(better, f, best_f), np.where(better, ss, best_s), np.where(better, tt, best_t)
    return best_f, best_s, best_t


class _PlateFrames:
    """Vectorised :class:`_PlateFrame` over broadcast arrays of poses."""

    def __init__(self, g: BodyGeometry, x, roll, pitch, hb, beam: int) -> None:
        x, roll, pitch, hb = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in (x, roll, pitch, hb)))
        sa, ca, sb, cb = np.sin(roll), np.cos(roll), np.sin(pitch), np.cos(pitch)
        y_lo, _ = g.beam_y_range(beam)
        dx, dy, dz = -x, y_lo, hb - g.height_m
        self.q0 = np.stack([(cb * dx - sb * dz) / g.a_m,
                            (sb * sa * dx + ca * dy + cb * sa * dz) / g.b_m,
                            (sb * ca * dx - sa * dy + cb * ca * dz) / g.c_m])
        self.V = np.stack([np.zeros_like(ca), ca / g.b_m, -sa / g.c_m])
        self.sa, self.ca, self.beta, self.g = sa, ca, pitch, g

    def f(self, theta):
        """(f, s, t, d f / d theta) of :meth:`_PlateFrame.f` over the arrays."""
        phi = theta - self.beta
        sp, cp = np.sin(phi), np.cos(phi)
        g = self.g
        U = np.stack([sp / g.a_m, self.sa * cp / g.b_m, self.ca * cp / g.c_m])
        f, s, t = _box_min_np(self.q0, U, self.V, g.beam_length_m, g.beam_width_m)
        q = self.q0 + s * U + t * self.V
        df = 2.0 * s * (q[0] * cp / g.a_m - q[1] * self.sa * sp / g.b_m - q[2] * self.ca * sp / g.c_m)
        return f, s, t, df

    def subset(self, idx: np.ndarray) -> "_PlateFrames":
        out = _PlateFrames.__new__(_PlateFrames)
        out.q0, out.V = self.q0.reshape(3, -1)[:, idx], self.V.reshape(3, -1)[:, idx]
        out.sa, out.ca, out.beta = self.sa.ravel()[idx], self.ca.ravel()[idx], self.beta.ravel()[idx]
        out.g = self.g
        return out


def deflection_angles(x_m, roll_rad, pitch_rad, hb_m, beam: int, geometry: BodyGeometry = PAPER_BODY,
                      scan_steps: int = 8, iterations: int = 10) -> np.ndarray:
    """Exact beam deflection (rad) over broadcast arrays of poses.

    A scan from theta = 0 brackets the first admissible angle (the smallest rotation that
    keeps the plate out of the body), then safeguarded Newton (bisection whenever a step
    leaves the bracket) closes it to about 1e-10 rad.
    """
    pf = _PlateFrames(geometry, x_m, roll_rad, pitch_rad, hb_m, beam)
    shape = pf.beta.shape
    theta = np.zeros(shape).ravel()
    idx = np.nonzero((pf.f(np.zeros(shape))[0] < 1.0).ravel())[0]
    if idx.size == 0:
        return theta.reshape(shape)
    sub = pf.subset(idx)
    n = idx.size
    lo, hi = np.zeros(n), np.full(n, THETA_MAX_RAD)
    found = np.zeros(n, dtype=bool)
    step = THETA_MAX_RAD / scan_steps
    for i in range(1, scan_steps + 1):
        th = np.full(n, i * step)
        ok = sub.f(th)[0] >= 1.0
        hi = np.where(ok & ~found, th, hi)
        lo = np.where(~found & ~ok, th, lo)
        found |= ok
        if found.all():
            break
    th = hi.copy()
    for _ in range(iterations):
        f, _, _, df = sub.f(th)
        out_ = f >= 1.0
        hi = np.where(out_, th, hi)
        lo = np.where(out_, lo, th)
        with np.errstate(divide="ignore", invalid="ignore"):
            nxt = th - (f - 1.0) / df
        bad = ~np.isfinite(nxt) | (nxt <= lo) | (nxt >= hi)
        th = np.where(bad, 0.5 * (lo + hi), nxt)
    f = sub.f(th)[0]
    th = np.where(f >= 1.0, th, hi)      # always report an admissible angle
    theta[idx] = np.where(found, th, THETA_MAX_RAD)
    return theta.reshape(shape)


def unit_contact_forces(x_m, roll_rad, pitch_rad, hb_m, beam: int,
                        geometry: BodyGeometry = PAPER_BODY) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For poses (arrays), (theta, lever_m, inward unit normal (3, ...)) of one beam.

    The contact force on the body is (restoring torque / lever) * normal, so for fixed
    geometry it is linear in k (and in tau_0): the estimator's closed form rests on this.
    """
    x, roll, pitch, hb = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in (x_m, roll_rad, pitch_rad, hb_m)))
    theta = deflection_angles(x, roll, pitch, hb, beam, geometry)
    pf = _PlateFrames(geometry, x, roll, pitch, hb, beam)
    _, s, t, _ = pf.f(theta)
    st, ct = np.sin(theta), np.cos(theta)
    y_lo, _ = geometry.beam_y_range(beam)
    rx, ry, rz = s * st - x, y_lo + t, hb + s * ct - geometry.height_m
    n = np.stack(_surface_normal(geometry, rx, ry, rz, np.sin(roll), np.cos(roll),
                                 np.sin(pitch), np.cos(pitch)))
    n /= np.linalg.norm(n, axis=0)
    lever = np.maximum(s * (ct * n[0] - st * n[2]), _LEVER_MIN_M)
    normal_in = np.where(theta > 0, -n, 0.0)
    return theta, lever, normal_in
