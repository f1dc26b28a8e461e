"""numba kernels behind :mod:`motion.pkm5.compiled` (imported only from there: importing this module imports numba).

Values: :func:`ik_values` repeats motion.pkm5.ik.leg_lengths operation by operation (same order, so the same IEEE
results; only the libm sin/cos may differ from numpy's by 1 ulp), on blocks of poses laid out one row per quantity
(structure of arrays) so that the arithmetic vectorises across poses. The elevation angles are left to numpy's SIMD
``arctan2`` over each cache-sized block (3 ns a value against 18 ns for a scalar libm atan2, which would be 2/3 of
the kernel's time), so they are numpy's own values. Jacobian: the same loop on 5-tuples
(value, d/dx, d/dy, d/dz, d/dangle), forward-mode dual numbers as in motion.dual, for the FK's Levenberg-Marquardt.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

_jit = njit(cache=True, nogil=True, error_model="numpy")
# dual-number helpers stay plain functions (LLVM inlines them): numba-level inline="always" on them made the FK
# kernel compile for ~50 s instead of ~10 s
_dual_op = _jit

# The packed geometry vector (motion.pkm5.compiled.pack_geometry): offsets of each field, in the order pack_geometry
# writes them. Like the IK block's layout below, they live here, beside the machine code that bakes them in: numba's
# cache is keyed on this file (a kernel's cached code does not notice a change of another file), so a layout defined
# elsewhere could change under a stale cached kernel. For the same reason no kernel here calls one of another file.
_OA12, _OA34, _OA56, _PD12, _PD34, _PD5, _PD6 = 0, 3, 6, 9, 12, 15, 18
_H = 21
_AB_ODD, _AB_EVEN, _AB5, _AB6, _CD_ODD, _CD_EVEN, _CD5, _CD6 = 22, 24, 26, 28, 30, 32, 34, 36
_LEG_MIN, _LEG_MAX, _TILT_MIN, _TILT_MAX = 38, 44, 50, 56
_A_LO, _A_HI, _B_LO, _B_HI, _PLANE_X, _PLANE_TOL = 62, 63, 64, 65, 66, 67
PACKED_SIZE = 68


# An IK block's scratch: one quantity a row, one pose a column (the layout that vectorises across poses), flat, with
# rows IK_BLOCK apart.
IK_BLOCK = 2048  # poses a block: its 27 rows of floats (442 KB) stay in the L2 cache
_IN_CA, _IN_SA, _IN_CB, _IN_SB, _IN_X, _IN_Y, _IN_Z, _IN_ALPHA, _IN_BETA = range(9)
IN_ROWS = 9
OUT_BU, OUT_BW, _OUT_LENGTH = 0, 6, 12  # six rows each, one a leg
OUT_ROWS = 18

# Failure flags (motion.pkm5.ik.Failure; numba cannot read an IntFlag)
_MODE, _ORIENTATION_RANGE, _ALPHA_PLANE, _LEG_LENGTH, _TILT = 1, 2, 4, 8, 16


# --- values ---------------------------------------------------------------------------------------------------
# Helpers of the IK take scalars and tuples only (no arrays: no reference counting in the loop) and are inlined by
# numba, which makes the pose loop ~1.5x faster than calls passing the geometry array.
_scalar = njit(cache=True, nogil=True, error_model="numpy", inline="always")


@_scalar
def _rotate(v, ca, sa, cb, sb):
    """R(beta, alpha) @ v with R = Ry(beta) Rx(alpha) (000 Eq. 5.4), as ik._rotate."""
    vx, vy, vz = v
    if vz != 0.0:
        t = sa * vy + ca * vz
        ry = ca * vy - sa * vz
    else:
        t = sa * vy
        ry = ca * vy
    return cb * vx + sb * t, ry, -sb * vx + cb * t


@_scalar
def _pair_plane(x, y, z, ca, sa, cb, sb, pd, oa, h):
    """ik._pair_plane: u, w of AD and cos, sin of the bracket angle delta."""
    dx, dy, dz = _rotate(pd, ca, sa, cb, sb)
    ax, ay, az = x + dx - oa[0], y + dy - oa[1], z + dz - oa[2]
    ex, ey, ez = sb * ca * h, -sa * h, cb * ca * h
    u = math.sqrt(ax * ax + ay * ay)
    pu, pv = ax + ex, ay + ey
    mu, mv = ax - ex, ay - ey
    u_e = math.sqrt(pu * pu + pv * pv)
    u_f = math.sqrt(mu * mu + mv * mv)
    du = 4.0 * (ax * ex + ay * ey) / (u_e + u_f)
    dw = 2.0 * ez
    r = math.sqrt(du * du + dw * dw)
    return u, az, dw / r, -du / r


@_scalar
def _leg(u, w, ab, cd, cos_d, sin_d):
    """ik._leg_in_plane: B->C in the plane (bu, bw)."""
    cu = cos_d * cd[0] - sin_d * cd[1]
    cw = sin_d * cd[0] + cos_d * cd[1]
    return u - ab[0] - cu, w - ab[1] - cw


@_scalar
def _v3(g, i):
    return g[i], g[i + 1], g[i + 2]


@_scalar
def _v2(g, i):
    return g[i], g[i + 1]


@_scalar
def _trig(angle):
    """cos, sin; exact 1, +-0 at +-0 without a libm call (the common case: one angle of the two is zero)."""
    if angle == 0.0:
        return 1.0, angle
    return math.cos(angle), math.sin(angle)


@_scalar
def _put(scratch, row, j, value):
    """scratch[row, j] of a block's scratch, flat with the compile-time row stride IK_BLOCK: constant strides let
    LLVM prove the rows apart and vectorise the pose loop without run-time alias checks."""
    scratch[row * IK_BLOCK + j] = value


@_scalar
def _get(scratch, row, j):
    return scratch[row * IK_BLOCK + j]


@_scalar
def _put_leg(outputs, leg, j, components):
    """Leg ``leg``'s in-plane B->C components (bu, bw) and its length."""
    bu, bw = components
    _put(outputs, OUT_BU + leg, j, bu)
    _put(outputs, OUT_BW + leg, j, bw)
    _put(outputs, _OUT_LENGTH + leg, j, math.sqrt(bu * bu + bw * bw))


@_scalar
def _check_block(n, inputs, outputs):
    """No bounds checks in compiled code: refuse a block that would write past its scratch."""
    if n > IK_BLOCK or inputs.size < IN_ROWS * IK_BLOCK or outputs.size < OUT_ROWS * IK_BLOCK:
        raise ValueError("an IK block holds at most IK_BLOCK poses and scratch of IN_ROWS, OUT_ROWS rows")


@_jit
def ik_values(poses, g, inputs, outputs):
    """Lengths |BC| of a block of poses (ik.leg_lengths) and the in-plane B->C components (bw, bu) whose angle is
    the leg elevation phi = atan2(bw, bu), into ``outputs`` rows _OUT_LENGTH, OUT_BW, OUT_BU.

    Two loops: the first takes each pose's sines and cosines (a branch and libm calls per pose) into ``inputs``,
    the second is straight-line arithmetic that LLVM vectorises across poses (4 or 8 square roots an instruction).
    """
    _check_block(poses.shape[0], inputs, outputs)
    for j in range(poses.shape[0]):
        ca, sa = _trig(poses[j, 3])
        cb, sb = _trig(poses[j, 4])
        _put(inputs, _IN_CA, j, ca)
        _put(inputs, _IN_SA, j, sa)
        _put(inputs, _IN_CB, j, cb)
        _put(inputs, _IN_SB, j, sb)
        _put(inputs, _IN_X, j, poses[j, 0])
        _put(inputs, _IN_Y, j, poses[j, 1])
        _put(inputs, _IN_Z, j, poses[j, 2])
        _put(inputs, _IN_ALPHA, j, poses[j, 3])
        _put(inputs, _IN_BETA, j, poses[j, 4])
    pd12, oa12, pd34, oa34 = _v3(g, _PD12), _v3(g, _OA12), _v3(g, _PD34), _v3(g, _OA34)
    pd5, pd6, oa56, h = _v3(g, _PD5), _v3(g, _PD6), _v3(g, _OA56), g[_H]
    ab_odd, cd_odd, ab_even, cd_even = _v2(g, _AB_ODD), _v2(g, _CD_ODD), _v2(g, _AB_EVEN), _v2(g, _CD_EVEN)
    ab5, cd5, ab6, cd6 = _v2(g, _AB5), _v2(g, _CD5), _v2(g, _AB6), _v2(g, _CD6)
    for j in range(poses.shape[0]):
        ca, sa, cb, sb = (
            _get(inputs, _IN_CA, j),
            _get(inputs, _IN_SA, j),
            _get(inputs, _IN_CB, j),
            _get(inputs, _IN_SB, j),
        )
        x, y, z, beta = (
            _get(inputs, _IN_X, j),
            _get(inputs, _IN_Y, j),
            _get(inputs, _IN_Z, j),
            _get(inputs, _IN_BETA, j),
        )
        u, w, cos_d, sin_d = _pair_plane(x, y, z, ca, sa, cb, sb, pd12, oa12, h)
        _put_leg(outputs, 0, j, _leg(u, w, ab_odd, cd_odd, cos_d, sin_d))
        _put_leg(outputs, 1, j, _leg(u, w, ab_even, cd_even, cos_d, sin_d))
        u, w, cos_d, sin_d = _pair_plane(x, y, z, ca, sa, cb, sb, pd34, oa34, h)
        _put_leg(outputs, 2, j, _leg(u, w, ab_odd, cd_odd, cos_d, sin_d))
        _put_leg(outputs, 3, j, _leg(u, w, ab_even, cd_even, cos_d, sin_d))
        # legs 5-6: the bracket turns with alpha in alpha mode only (pkm5.md §3.2 step 4b); selects, not branches
        cos_56 = ca if beta == 0.0 else 1.0
        sin_56 = sa if beta == 0.0 else 0.0
        dx, dy, dz = _rotate(pd5, ca, sa, cb, sb)
        ax, ay, az = x + dx - oa56[0], y + dy - oa56[1], z + dz - oa56[2]
        _put_leg(outputs, 4, j, _leg(ay, math.sqrt(ax * ax + az * az), ab5, cd5, cos_56, sin_56))
        dx, dy, dz = _rotate(pd6, ca, sa, cb, sb)
        ax, ay, az = x + dx - oa56[0], y + dy - oa56[1], z + dz - oa56[2]
        _put_leg(outputs, 5, j, _leg(ay, math.sqrt(ax * ax + az * az), ab6, cd6, cos_56, sin_56))


@_scalar
def _v6(g, i):
    return g[i], g[i + 1], g[i + 2], g[i + 3], g[i + 4], g[i + 5]


@_jit
def ik_limits(inputs, outputs, g, check_limits, lengths, tilts, failure, length_ok, tilt_ok):
    """A block's results into its rows of the (N, 6) outputs, given flat (``lengths``, ``tilts``, ``length_ok``,
    ``tilt_ok``: 6 values a pose), with the failure flags and per-leg windows of inverse_kinematics; ``outputs``
    rows OUT_BW hold the tilts (arctan2 applied). Branch-free per leg, so it vectorises across poses too."""
    a_lo, a_hi, b_lo, b_hi, plane_x, plane_tol = g[_A_LO], g[_A_HI], g[_B_LO], g[_B_HI], g[_PLANE_X], g[_PLANE_TOL]
    leg_min, leg_max, tilt_min, tilt_max = _v6(g, _LEG_MIN), _v6(g, _LEG_MAX), _v6(g, _TILT_MIN), _v6(g, _TILT_MAX)
    _check_block(failure.shape[0], inputs, outputs)
    n = failure.shape[0]
    if lengths.size < 6 * n or tilts.size < 6 * n or length_ok.size < 6 * n or tilt_ok.size < 6 * n:
        raise ValueError("lengths, tilts, length_ok and tilt_ok need 6 values a pose")
    for j in range(n):
        x, alpha, beta = _get(inputs, _IN_X, j), _get(inputs, _IN_ALPHA, j), _get(inputs, _IN_BETA, j)
        flags = _MODE if (alpha != 0.0) & (beta != 0.0) else 0
        if check_limits:
            if (alpha < a_lo) | (alpha > a_hi) | (beta < b_lo) | (beta > b_hi):
                flags |= _ORIENTATION_RANGE
            if (alpha != 0.0) & (abs(x - plane_x) > plane_tol):
                flags |= _ALPHA_PLANE
        all_lengths_ok, all_tilts_ok = True, True
        for leg in range(6):
            length, tilt = _get(outputs, _OUT_LENGTH + leg, j), _get(outputs, OUT_BW + leg, j)
            lengths[6 * j + leg] = length
            tilts[6 * j + leg] = tilt
            length_in = (length > leg_min[leg]) & (length < leg_max[leg]) if check_limits else True
            tilt_in = (tilt > tilt_min[leg]) & (tilt < tilt_max[leg]) if check_limits else True
            length_ok[6 * j + leg] = length_in
            tilt_ok[6 * j + leg] = tilt_in
            all_lengths_ok &= length_in
            all_tilts_ok &= tilt_in
        if not all_lengths_ok:
            flags |= _LEG_LENGTH
        if not all_tilts_ok:
            flags |= _TILT
        failure[j] = flags


# --- dual numbers: (value, d/dx, d/dy, d/dz, d/dangle) ---------------------------------------------------------
@_dual_op
def _add(a, b):
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2], a[3] + b[3], a[4] + b[4])


@_dual_op
def _sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2], a[3] - b[3], a[4] - b[4])


@_dual_op
def _shift(a, c):
    return (a[0] + c, a[1], a[2], a[3], a[4])


@_dual_op
def _scale(a, c):
    return (a[0] * c, a[1] * c, a[2] * c, a[3] * c, a[4] * c)


@_dual_op
def _mul(a, b):
    return (
        a[0] * b[0],
        a[1] * b[0] + b[1] * a[0],
        a[2] * b[0] + b[2] * a[0],
        a[3] * b[0] + b[3] * a[0],
        a[4] * b[0] + b[4] * a[0],
    )


@_dual_op
def _div(a, b):
    inv = 1.0 / b[0]
    return _mul(a, (inv, -b[1] * inv * inv, -b[2] * inv * inv, -b[3] * inv * inv, -b[4] * inv * inv))


@_dual_op
def _hypot(a, b):
    """sqrt(a^2 + b^2); d = (a da + b db) / r."""
    r = math.sqrt(a[0] * a[0] + b[0] * b[0])
    ua, ub = a[0] / r, b[0] / r
    return (r, a[1] * ua + b[1] * ub, a[2] * ua + b[2] * ub, a[3] * ua + b[3] * ub, a[4] * ua + b[4] * ub)


@_dual_op
def _d_cos_sin(a):
    c, s = math.cos(a[0]), math.sin(a[0])
    return (c, -s * a[1], -s * a[2], -s * a[3], -s * a[4]), (s, c * a[1], c * a[2], c * a[3], c * a[4])


@_dual_op
def _d_rotate(g, i, ca, sa, cb, sb):
    vx, vy, vz = g[i], g[i + 1], g[i + 2]
    if vz != 0.0:
        t = _add(_scale(sa, vy), _scale(ca, vz))
        ry = _sub(_scale(ca, vy), _scale(sa, vz))
    else:
        t = _scale(sa, vy)
        ry = _scale(ca, vy)
    return _add(_scale(cb, vx), _mul(sb, t)), ry, _add(_scale(sb, -vx), _mul(cb, t))


@_dual_op
def _d_leg(u, w, g, ab, cd, cos_d, sin_d):
    cu = _sub(_scale(cos_d, g[cd]), _scale(sin_d, g[cd + 1]))
    cw = _add(_scale(sin_d, g[cd]), _scale(cos_d, g[cd + 1]))
    return _hypot(_sub(_shift(u, -g[ab]), cu), _sub(_shift(w, -g[ab + 1]), cw))


@_jit
def _residual(q, mode, target, g, r, jac):
    """IK(q) - target into r (6,) and its Jacobian d/d(x, y, z, angle) into jac (6, 4) (fk._residual)."""
    x = (q[0], 1.0, 0.0, 0.0, 0.0)
    y = (q[1], 0.0, 1.0, 0.0, 0.0)
    z = (q[2], 0.0, 0.0, 1.0, 0.0)
    angle = (q[3], 0.0, 0.0, 0.0, 1.0)
    zero = (0.0, 0.0, 0.0, 0.0, 0.0)
    alpha = angle if mode == 1 else zero
    beta = angle if mode == 2 else zero
    ca, sa = _d_cos_sin(alpha)
    cb, sb = _d_cos_sin(beta)
    h = g[_H]
    leg = 0
    for pair in range(2):
        pd, oa = (_PD12, _OA12) if pair == 0 else (_PD34, _OA34)
        dx, dy, dz = _d_rotate(g, pd, ca, sa, cb, sb)
        ax, ay, az = _shift(_add(x, dx), -g[oa]), _shift(_add(y, dy), -g[oa + 1]), _shift(_add(z, dz), -g[oa + 2])
        ex, ey, ez = _scale(_mul(sb, ca), h), _scale(sa, -h), _scale(_mul(cb, ca), h)
        u = _hypot(ax, ay)
        u_e = _hypot(_add(ax, ex), _add(ay, ey))
        u_f = _hypot(_sub(ax, ex), _sub(ay, ey))
        du = _div(_scale(_add(_mul(ax, ex), _mul(ay, ey)), 4.0), _add(u_e, u_f))
        dw = _scale(ez, 2.0)
        rr = _hypot(du, dw)
        cos_d, sin_d = _div(dw, rr), _scale(_div(du, rr), -1.0)
        for ab, cd in ((_AB_ODD, _CD_ODD), (_AB_EVEN, _CD_EVEN)):
            length = _d_leg(u, az, g, ab, cd, cos_d, sin_d)
            r[leg] = length[0] - target[leg]
            for c in range(4):
                jac[leg, c] = length[c + 1]
            leg += 1
    one = (1.0, 0.0, 0.0, 0.0, 0.0)
    cos_56, sin_56 = (ca, sa) if beta[0] == 0.0 else (one, zero)
    for pd, ab, cd in ((_PD5, _AB5, _CD5), (_PD6, _AB6, _CD6)):
        dx, dy, dz = _d_rotate(g, pd, ca, sa, cb, sb)
        ax, ay, az = (
            _shift(_add(x, dx), -g[_OA56]),
            _shift(_add(y, dy), -g[_OA56 + 1]),
            _shift(_add(z, dz), -g[_OA56 + 2]),
        )
        length = _d_leg(ay, _hypot(ax, az), g, ab, cd, cos_56, sin_56)
        r[leg] = length[0] - target[leg]
        for c in range(4):
            jac[leg, c] = length[c + 1]
        leg += 1


# --- Levenberg-Marquardt, one pose -----------------------------------------------------------------------------
@_jit
def _solve(a, b, k, out):
    """out = a^-1 b for a (k, k) by Gaussian elimination with partial pivoting (a and b are overwritten)."""
    for col in range(k):
        pivot = col
        for row in range(col + 1, k):
            if abs(a[row, col]) > abs(a[pivot, col]):
                pivot = row
        if pivot != col:
            for c in range(k):
                a[col, c], a[pivot, c] = a[pivot, c], a[col, c]
            b[col], b[pivot] = b[pivot], b[col]
        for row in range(col + 1, k):
            factor = a[row, col] / a[col, col]
            for c in range(col, k):
                a[row, c] -= factor * a[col, c]
            b[row] -= factor * b[col]
    for row in range(k - 1, -1, -1):
        total = b[row]
        for c in range(row + 1, k):
            total -= a[row, c] * out[c]
        out[row] = total / a[row, row]


@_jit
def _copy4(target, source):
    """target[:4] = source[:4] as a loop (slice assignment costs seconds of numba compile time)."""
    for a in range(4):
        target[a] = source[a]


@_jit
def _cost(r):
    total = 0.0
    for i in range(6):
        total += r[i] * r[i]
    return total


@_jit
def _levenberg_marquardt(q, k, mode, target, g, max_iter, step_tol, work):
    """fk._levenberg_marquardt for one pose, q (4,) updated in place; returns cost, iterations, stationary.

    Damping, acceptance and stopping rules are those of the batched numpy solver, row for row. The residual is
    evaluated at one call site (the start point, then each trial point), which keeps the machine code, and the
    compile time, to one copy of the dual-number IK.
    """
    # rows of C-contiguous work arrays stay C-contiguous, so every kernel is compiled for one layout only
    vectors, matrices = work
    r, r_new, grad, step, q_new = vectors[0], vectors[1], vectors[2], vectors[3], vectors[4]
    jac, jac_new, normal = matrices[0], matrices[1], matrices[2]
    _copy4(q_new, q)
    cost, damping, iterations, done = 0.0, 1e-3, 0, False
    for evaluation in range(max_iter + 1):
        _residual(q_new, mode, target, g, r_new, jac_new)
        cost_new = _cost(r_new)
        if evaluation == 0 or cost_new <= cost:
            _copy4(q, q_new)
            for i in range(6):
                r[i] = r_new[i]
                for a in range(4):
                    jac[i, a] = jac_new[i, a]
            cost = cost_new
        if evaluation == 0:
            done = cost < 1e-24
        else:
            damping = max(damping * 0.3, 1e-12) if cost_new <= cost else damping * 10.0
            iterations += 1
            largest = 0.0
            for a in range(k):
                largest = max(largest, abs(step[a]))
            # a step below tolerance means no further progress, whether or not it was accepted
            done = largest < step_tol or cost < 1e-24 or damping > 1e12
        if done or evaluation == max_iter:
            break
        for a in range(k):
            total = 0.0
            for i in range(6):
                total += jac[i, a] * r[i]
            grad[a] = total
            for b in range(k):
                total = 0.0
                for i in range(6):
                    total += jac[i, a] * jac[i, b]
                normal[a, b] = total
        for a in range(k):
            normal[a, a] += damping * normal[a, a]
        _solve(normal, grad, k, step)
        for a in range(k):
            q_new[a] = q[a] - step[a]
    return cost, iterations, done


@_jit
def _fk_with_restarts(target, q, mode, restarts, n_restarts, g, max_iter, step_tol, retry_above_mm, work):
    """LM from q, then from each restart while the residual RMS exceeds retry_above_mm, keeping the best."""
    k = 3 if mode == 0 else 4
    trial = work[0][5]
    _copy4(trial, q)
    cost, iterations, done = np.inf, 0, False
    for j in range(-1, n_restarts):
        if j >= 0:
            if not math.sqrt(cost / 6) > retry_above_mm:
                break
            _copy4(trial, restarts[j])
        cost_r, iterations_r, done_r = _levenberg_marquardt(trial, k, mode, target, g, max_iter, step_tol, work)
        if j < 0 or cost_r < cost:
            _copy4(q, trial)
            cost, iterations, done = cost_r, iterations_r, done_r
    return cost, iterations, done


@_jit
def _workspace():
    """Scratch of one LM solve: six vectors (r, r_new, grad, step, q_new, trial) and three 6 x 4 matrices."""
    return np.zeros((6, 6)), np.zeros((3, 6, 4))


@_jit
def fk_batch(target, q, mode, restarts, n_restarts, g, max_iter, step_tol, retry_above_mm, cost, iterations, done):
    """The FK of N rows of one mode; q (N, 4) holds the initial guesses and receives the solutions."""
    work = _workspace()
    for i in range(target.shape[0]):
        cost[i], iterations[i], done[i] = _fk_with_restarts(
            target[i], q[i], mode, restarts, n_restarts, g, max_iter, step_tol, retry_above_mm, work
        )
