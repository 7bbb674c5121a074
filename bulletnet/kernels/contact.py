"""Contact of the net's spheres with the debris and with each other (Eq. 6 and Eq. 12),
compiled with numba.

Normal force (Eq. 6, no adhesion): F = k_c delta + c_c d(delta)/dt while the spheres overlap
(delta > 0) and F > 0, zero otherwise, with each pair's own k_c and c_c (Tables 5-6). At the
paper's k_c ~ 4e9 N/m on a 2 g node the contact lasts ~2 us; no practical step resolves that,
and an explicit penalty needs steps below 1e-6 s. So the normal motion of a node in contact
is integrated *exactly* over each step: with the other forces on the node held at their
step value, the relative normal coordinate obeys a linear damped oscillator while in contact
and free flight otherwise, and :func:`normal_step` follows it through every touch-down and
lift-off inside the step in closed form. Any step then gives the contact's own rebound
(restitution exp(-pi xi / sqrt(1 - xi^2))), its static penetration F / k_c and its contact
time; what a large step loses is only the variation of the *other* forces within the step.

``contact.model = "implicit"`` replaces this by a backward-Euler step of the same law
(:func:`implicit_normal_step`), which is what a constraint solver does (Vortex, PyBullet):
stable too, but at practical steps it ends every impact inelastically.

Friction (Eq. 12): regularized Coulomb. Below the static bound the tangential relative
velocity is damped viscously with the inverse slip coefficient 1/s [N s/m] over the time in
contact (exact exponential decay); if the impulse that takes exceeds mu_s times the normal
impulse, the node slides and receives mu_k times the normal impulse against its slip (never
more than stops it). It is isotropic in the tangent plane (the paper's Vortex applies it per
component of a contact frame).

The debris is a rigid body moving at constant velocity over a step; the impulses on it are
summed (force and moment about its centre of mass) for its own dynamics. Where a node is
against the debris (its signed distance and normal) is :mod:`bulletnet.kernels.geometry`'s.
"""

from __future__ import annotations

import math

import numba as nb

MAX_EVENTS = 16
"""Touch-down / lift-off events followed within one step before the rest of the step is
taken in the current phase [-]."""


@nb.njit(cache=True, error_model="numpy")
def _first_root(c2, c1, c0, t_max):
    """Smallest root t in (0, t_max] of c2 t^2 + c1 t + c0 = 0, or -1.0 if none."""
    eps = 1e-13 * t_max
    best = -1.0
    if c2 == 0.0:
        if c1 != 0.0:
            t = -c0 / c1
            if eps < t <= t_max:
                best = t
        return best
    disc = c1 * c1 - 4.0 * c2 * c0
    if disc < 0.0:
        return -1.0
    q = -0.5 * (c1 + math.copysign(math.sqrt(disc), c1))
    roots = (q / c2, c0 / q if q != 0.0 else -1.0)
    for t in roots:
        if eps < t <= t_max and (best < 0.0 or t < best):
            best = t
    return best


@nb.njit(cache=True, error_model="numpy")
def _oscillator(s, u, a, k, c, m, t):
    """Gap s [m] and gap rate u [m/s] after time t [s] in contact, from (s, u): the damped
    oscillator m s'' = m a - k s - c s' (underdamped: c^2 < 4 k m)."""
    s_eq = m * a / k
    sigma = c / (2.0 * m)
    wd = math.sqrt(k / m - sigma * sigma)
    y0 = s - s_eq
    b = (u + sigma * y0) / wd
    e = math.exp(-sigma * t)
    cs, sn = math.cos(wd * t), math.sin(wd * t)
    y = e * (y0 * cs + b * sn)
    v = e * ((b * wd - sigma * y0) * cs - (y0 * wd + sigma * b) * sn)
    return s_eq + y, v


@nb.njit(cache=True, error_model="numpy")
def _force(s, u, k, c):
    """Contact force -k s - c u [N] at gap s [m] (negative: overlap) and gap rate u [m/s]."""
    return -k * s - c * u


@nb.njit(cache=True, error_model="numpy")
def _lift_off(s, u, a, k, c, m, t_max):
    """First time in (0, t_max] at which the contact force of an oscillator starting in
    contact at (s, u) falls to zero, or -1.0 if it stays positive. The force is
    F_eq + exp(-sigma t) R cos(wd t - phi); its minima rise monotonically towards F_eq, so
    only the first minimum needs checking, and the root is bracketed by it and the
    maximum (or start) before it."""
    sigma = c / (2.0 * m)
    wd = math.sqrt(k / m - sigma * sigma)
    # F(t) - F_eq = exp(-sigma t) (P cos wd t + Q sin wd t)
    s_eq = m * a / k
    y0 = s - s_eq
    b = (u + sigma * y0) / wd
    p = -k * y0 - c * (b * wd - sigma * y0)
    q = -k * b + c * (y0 * wd + sigma * b)
    if p == 0.0 and q == 0.0:
        return -1.0 if -k * s_eq > 0.0 else 1e-13 * t_max
    phi = math.atan2(q, p)
    theta = -math.atan2(sigma, wd)  # extrema at wd t - phi = theta + n pi
    n0 = math.floor(-(theta + phi) / math.pi) + 1
    t_a = (theta + n0 * math.pi + phi) / wd
    t_b = t_a + math.pi / wd
    fa = _force(*_oscillator(s, u, a, k, c, m, t_a), k, c)
    fb = _force(*_oscillator(s, u, a, k, c, m, t_b), k, c)
    if fa <= fb:
        lo, hi, f_min = 0.0, t_a, fa
    else:
        lo, hi, f_min = t_a, t_b, fb
    if f_min > 0.0 or lo >= t_max:
        return -1.0
    if _force(*_oscillator(s, u, a, k, c, m, min(hi, t_max)), k, c) > 0.0:
        return -1.0
    for _ in range(80):  # bisection on the monotone bracket [lo, hi]
        mid = 0.5 * (lo + hi)
        if _force(*_oscillator(s, u, a, k, c, m, mid), k, c) > 0.0:
            lo = mid
        else:
            hi = mid
        if hi - lo <= 1e-15 * hi:
            break
    return hi


@nb.njit(cache=True, error_model="numpy")
def normal_step(s, u, a, k, c, m, dt):
    """Exact normal motion over one step ``dt`` [s] of a sphere against a surface: gap s [m]
    (negative: overlap), gap rate u [m/s], other forces' acceleration along the normal
    a [m/s^2] (constant over the step), pair stiffness k [N/m], damping c [N s/m] and
    (reduced) mass m [kg]. Returns (s, u, time in contact [s]) at the end of the step."""
    rem = dt
    contact_time = 0.0
    in_contact = s <= 0.0 and _force(s, u, k, c) > 0.0
    for _ in range(MAX_EVENTS):
        if rem <= 0.0:
            break
        if in_contact:
            t = _lift_off(s, u, a, k, c, m, rem)
            step = rem if t < 0.0 else t
            s, u = _oscillator(s, u, a, k, c, m, step)
            contact_time += step
            rem -= step
            in_contact = False
            continue
        # free flight: s + u t + a t^2 / 2; contact starts when the gap closes (from
        # outside) or, inside the overlap, when the force turns positive
        if s > 0.0:
            t = _first_root(0.5 * a, u, s, rem)
        elif s == 0.0 and (u < 0.0 or (u == 0.0 and a < 0.0)):
            t = 0.0  # touching and pressing on: contact starts now
        elif s < 0.0 and _force(s, u, k, c) == 0.0 and -k * u - c * a > 0.0:
            t = 0.0  # the force is zero and rising: contact starts now
        elif s == 0.0:
            t = _first_root(0.5 * a, u, s, rem)
        else:
            t = _first_root(-0.5 * k * a, -(k * u + c * a), -(k * s + c * u), rem)
            t_out = _first_root(0.5 * a, u, s, rem)
            if t_out > 0.0 and (t < 0.0 or t_out < t):  # leaves the overlap first
                u = u + a * t_out
                s = 0.0
                rem -= t_out
                continue
        if t < 0.0:
            s, u = s + u * rem + 0.5 * a * rem * rem, u + a * rem
            rem = 0.0
            break
        s, u = s + u * t + 0.5 * a * t * t, u + a * t
        if s > 0.0:
            s = 0.0
        rem -= t
        in_contact = True
    if rem > 0.0:  # event budget spent: finish in the current phase
        if in_contact:
            s, u = _oscillator(s, u, a, k, c, m, rem)
            contact_time += rem
        else:
            s, u = s + u * rem + 0.5 * a * rem * rem, u + a * rem
    return s, u, contact_time


@nb.njit(cache=True, error_model="numpy")
def implicit_normal_step(s, u, a, k, c, m, dt):
    """Backward Euler on Eq. 6 over one step, as a constraint solver treats contact (Vortex,
    PyBullet): the force acts if it is positive at the step's end with the gap there
    negative. At dt^2 k >> m this removes the overlap in one step and ends the approach:
    a perfectly inelastic touch-down whatever the pair's damping. Same arguments and
    returns as :func:`normal_step` (contact time: the whole step if in contact)."""
    u1 = (m * (u + a * dt) - dt * k * s) / (m + dt * c + dt * dt * k)
    s1 = s + dt * u1
    if s1 < 0.0 and _force(s1, u1, k, c) > 0.0:
        return s1, u1, dt
    u1 = u + a * dt
    return s + dt * u1, u1, 0.0


@nb.njit(cache=True, error_model="numpy")
def stick_fraction(contact_time, m, slip):
    """The share [-] of a slip's momentum that the viscous stick of Eq. 12 takes over
    ``contact_time`` [s], mass ``m`` [kg] and slip coefficient ``slip`` [s/kg]:
    1 - exp(-t / (m s))."""
    return -math.expm1(-contact_time / (m * slip))


@nb.njit(cache=True, error_model="numpy")
def limited_friction(stick, normal_impulse, m, speed, mu_s, mu_k):
    """Magnitude [N s] of the friction impulse of Eq. 12 whose viscous stick would be
    ``stick`` [N s]: the stick if it stays within mu_s times ``normal_impulse`` [N s], else
    mu_k times it, at most what stops the slip ``speed`` [m/s] of mass ``m`` [kg]."""
    if stick <= mu_s * normal_impulse:
        return stick
    return min(mu_k * normal_impulse, m * speed)


@nb.njit(cache=True, error_model="numpy")
def friction_impulse(speed, normal_impulse, contact_time, m, slip, mu_s, mu_k):
    """Magnitude [N s] of the friction impulse against a tangential slip ``speed`` [m/s]
    (Eq. 12): the viscous stick over ``contact_time`` [s] with the inverse slip coefficient
    1 / ``slip`` [N s/m] (:func:`stick_fraction`), limited by :func:`limited_friction`."""
    if speed <= 0.0 or contact_time <= 0.0:
        return 0.0
    return limited_friction(m * speed * stick_fraction(contact_time, m, slip),
                            normal_impulse, m, speed, mu_s, mu_k)
