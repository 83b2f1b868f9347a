/* Plant dynamics: RLC coils -> field -> torque/force -> swimmer motion in a tank. */
#include "plant.h"
#include "vec3.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#define TWO_PI (2.0 * M_PI)
#ifndef REFRESH_DISTANCE
#define REFRESH_DISTANCE 2.5e-4  /* [m] re-evaluate G, dG/dx when the swimmer moved this far */
#endif

/* -------------------------------------------------------------- coil drive */

/* Coil drive held constant over one macro step. */
typedef struct {
    double omega;                    /* [rad/s] */
    double vamp[N_COILS];            /* [V] */
    double cphi[N_COILS], sphi[N_COILS];
    double vmax;                     /* [V] */
    double ire[N_COILS], iim[N_COILS]; /* steady-state current phasor [A] (lag off) */
} Drive;

static void drive_from_inputs(const Plant *pl, Drive *d)
{
    d->omega = TWO_PI * P(pl, freq);
    d->vmax = P(pl, V_supply_max);
    double R = P(pl, R_coil), L = P(pl, L_coil), C = P(pl, C_coil);
    double X = (d->omega != 0.0) ? d->omega * L - 1.0 / (d->omega * C) : 0.0;
    double z2 = R * R + X * X;
    for (int i = 0; i < N_COILS; ++i) {
        double phi = pl->r[R_V_phase_1 + i];
        d->vamp[i] = pl->r[R_V_amp_1 + i];
        d->cphi[i] = cos(phi);
        d->sphi[i] = sin(phi);
        /* Phasor I = V e^{i phi} / (R + i X), amplitude clipped to the supply. */
        double vc = fmax(-d->vmax, fmin(d->vmax, d->vamp[i]));
        double vr = vc * d->cphi[i], vi = vc * d->sphi[i];
        if (d->omega != 0.0) {
            d->ire[i] = (vr * R + vi * X) / z2;
            d->iim[i] = (vi * R - vr * X) / z2;
        } else {                      /* DC: the series capacitor blocks it */
            d->ire[i] = 0.0;
            d->iim[i] = 0.0;
        }
    }
}

/* Currents I [A] and dI/dt [A/s] at time t; for actuation lag also dq/dt. */
static void coil_currents(const Plant *pl, const Drive *d, double t, const double *y,
                          double I[N_COILS], double dI[N_COILS])
{
    double c = cos(d->omega * t), s = sin(d->omega * t);
    if (ON(pl, actuation_lag_on)) {
        double R = P(pl, R_coil), invL = 1.0 / P(pl, L_coil), invC = 1.0 / P(pl, C_coil);
        for (int i = 0; i < N_COILS; ++i) {
            double v = d->vamp[i] * (c * d->cphi[i] - s * d->sphi[i]);
            v = fmax(-d->vmax, fmin(d->vmax, v));
            I[i] = y[Y_I + i];
            dI[i] = (v - R * I[i] - y[Y_Q + i] * invC) * invL;
        }
    } else {
        for (int i = 0; i < N_COILS; ++i) {
            I[i] = d->ire[i] * c - d->iim[i] * s;
            dI[i] = -d->omega * (d->ire[i] * s + d->iim[i] * c);
        }
    }
}

/* Field B [T] at p from currents I via the linearisation about p_ref;
 * optionally the total gradient Jt[a][b] = dB_a/dx_b [T/m]. */
static void field_at(const Plant *pl, const double I[N_COILS], const double p[3],
                     double B[3], double Jt[3][3])
{
    double J[3][3] = {{0}};
    double dp[3] = {p[0] - pl->p_ref[0], p[1] - pl->p_ref[1], p[2] - pl->p_ref[2]};
    B[0] = B[1] = B[2] = 0.0;
    for (int i = 0; i < N_COILS; ++i) {
        for (int a = 0; a < 3; ++a) {
            B[a] += I[i] * pl->G_ref[i][a];
            for (int b = 0; b < 3; ++b) J[a][b] += I[i] * pl->J_ref[i][a][b];
        }
    }
    for (int a = 0; a < 3; ++a) {
        B[a] += J[a][0] * dp[0] + J[a][1] * dp[1] + J[a][2] * dp[2];
        if (Jt) for (int b = 0; b < 3; ++b) Jt[a][b] = J[a][b];
    }
}

static void refresh_field(Plant *pl)
{
    for (int a = 0; a < 3; ++a) pl->p_ref[a] = pl->y[Y_P + a];
    coil_fields(&pl->geom, pl->p_ref, pl->G_ref, pl->J_ref);
}

/* ------------------------------------------------------------- dynamics */

/* Drag multiplier near the walls: 1 + gain * sum over the six walls of exp(-gap/length). */
static double wall_factor(const Plant *pl, const double p[3])
{
    if (!ON(pl, wall_drag_on)) return 1.0;
    double lim = P(pl, tank_half) - P(pl, wall_margin), len = P(pl, wall_drag_length), s = 0.0;
    for (int k = 0; k < 3; ++k) {
        s += exp(-fmax(lim - p[k], 0.0) / len);
        s += exp(-fmax(lim + p[k], 0.0) / len);
    }
    return 1.0 + P(pl, wall_drag_gain) * s;
}

/* The external force input (an effect applied from outside) added to F [N]: F_ext, held over
 * the step, plus its linear-in-state part F_ext_dp (p - p_0) + F_ext_dv (v - v_0) about the
 * state at the step's start, so a state-dependent effect follows the internal steps. */
static void external_force(const Plant *pl, const double p[3], const double v[3], double F[3])
{
    const double *dp = pl->r + R_F_ext_dp_xx, *dv = pl->r + R_F_ext_dv_xx;
    double e[3] = {p[0] - pl->ext_p0[0], p[1] - pl->ext_p0[1], p[2] - pl->ext_p0[2]};
    double w[3] = {v[0] - pl->ext_v0[0], v[1] - pl->ext_v0[1], v[2] - pl->ext_v0[2]};
    for (int a = 0; a < 3; ++a)
        F[a] += pl->r[R_F_ext_x + a] + dp[3 * a] * e[0] + dp[3 * a + 1] * e[1] + dp[3 * a + 2] * e[2]
              + dv[3 * a] * w[0] + dv[3 * a + 1] * w[1] + dv[3 * a + 2] * w[2];
}

static void derivatives(const Plant *pl, const Drive *d, double t, const double *y, double *dy)
{
    double I[N_COILS], dI[N_COILS];
    coil_currents(pl, d, t, y, I, dI);
    for (int i = 0; i < N_COILS; ++i) {
        dy[Y_Q + i] = ON(pl, actuation_lag_on) ? I[i] : 0.0;
        dy[Y_I + i] = ON(pl, actuation_lag_on) ? dI[i] : 0.0;
    }

    const double *p = y + Y_P, *v = y + Y_V, *q = y + Y_QUAT;
    double B[3], Jt[3][3], u[3], mh[3], m[3], tau[3], w[3];
    field_at(pl, I, p, B, Jt);
    body_axes(q, u, mh);
    for (int a = 0; a < 3; ++a) m[a] = P(pl, moment) * mh[a];

    /* Overdamped rotation: omega = D^-1 (m x B), D = c_ax u u^T + c_perp (1 - u u^T). */
    cross3(m, B, tau);
    double tau_ax = dot3(tau, u);
    double wa = tau_ax / P(pl, rot_drag_axial);
    double cp = ON(pl, heading_dynamics_on) ? 1.0 / P(pl, rot_drag_perp) : 0.0;
    for (int a = 0; a < 3; ++a) w[a] = wa * u[a] + cp * (tau[a] - tau_ax * u[a]);
    /* dq/dt = 1/2 (0, w) (x) q */
    dy[Y_QUAT + 0] = -0.5 * (w[0] * q[1] + w[1] * q[2] + w[2] * q[3]);
    dy[Y_QUAT + 1] = 0.5 * (q[0] * w[0] + w[1] * q[3] - w[2] * q[2]);
    dy[Y_QUAT + 2] = 0.5 * (q[0] * w[1] + w[2] * q[1] - w[0] * q[3]);
    dy[Y_QUAT + 3] = 0.5 * (q[0] * w[2] + w[0] * q[2] - w[1] * q[1]);
    double spin = dot3(w, u);           /* body spin about the long axis [rad/s] */
    dy[Y_SPIN] = spin;

    /* Translation: propulsion, drag, weight - buoyancy, gradient force. */
    double F[3], vr[3];
    double thrust = P(pl, handedness) * P(pl, prop_coeff) * spin;
    for (int a = 0; a < 3; ++a) {
        F[a] = thrust * u[a];
        vr[a] = v[a] - (ON(pl, background_flow_on) ? pl->r[R_flow_x + a] : 0.0);
    }
    double fw = wall_factor(pl, p);
    double c_ax = P(pl, drag_axial);
    double c_perp = ON(pl, anisotropic_drag_on) ? c_ax * P(pl, anisotropy_ratio) : c_ax;
    double v_ax = dot3(vr, u);
    for (int a = 0; a < 3; ++a)
        F[a] -= fw * (c_ax * v_ax * u[a] + c_perp * (vr[a] - v_ax * u[a]));
    if (ON(pl, quadratic_drag_on)) {
        double speed = sqrt(dot3(vr, vr));
        if (speed > 0.0) {
            double ca = fabs(v_ax) / speed, sa = sqrt(fmax(0.0, 1.0 - ca * ca));
            double dia = P(pl, diameter);
            double area = dia * P(pl, length) * sa + 0.25 * M_PI * dia * dia * ca;
            double k = 0.5 * P(pl, rho_fluid) * P(pl, quad_drag_cd) * area * speed;
            for (int a = 0; a < 3; ++a) F[a] -= k * vr[a];
        }
    }
    F[2] -= (P(pl, mass) - P(pl, rho_fluid) * P(pl, volume)) * P(pl, g);
    if (ON(pl, gradient_force_on)) {
        double s = P(pl, gradient_force_scale);   /* F_b = sum_a m_a dB_a/dx_b */
        for (int b = 0; b < 3; ++b) F[b] += s * (m[0] * Jt[0][b] + m[1] * Jt[1][b] + m[2] * Jt[2][b]);
    }
    external_force(pl, p, v, F);
    for (int a = 0; a < 3; ++a) dy[Y_P + a] = v[a];
    if (!ON(pl, added_mass_on)) {
        double inv_m = 1.0 / P(pl, mass);
        for (int a = 0; a < 3; ++a) dy[Y_V + a] = F[a] * inv_m;
        return;
    }
    /* Added mass: the water's impulse M_a v_r, M_a = rho V (k_ax u u^T + k_perp (1 - u u^T)),
     * turns with the body: (m + M_a) dv/dt = F - (dM_a/dt) v_r, where
     * dM_a/dt = rho V (k_ax - k_perp) (du u^T + u du^T) and du/dt = w x u.
     * m + M_a = alpha 1 + beta u u^T, inverted in closed form. */
    double rv = P(pl, rho_fluid) * P(pl, volume);
    double alpha = P(pl, mass) + rv * P(pl, added_mass_perp);
    double beta = rv * (P(pl, added_mass_axial) - P(pl, added_mass_perp));
    double du[3];
    cross3(w, u, du);
    double du_vr = dot3(du, vr);
    for (int a = 0; a < 3; ++a) F[a] -= beta * (du[a] * v_ax + u[a] * du_vr);
    double uF = dot3(u, F), s = beta / (alpha + beta);
    for (int a = 0; a < 3; ++a) dy[Y_V + a] = (F[a] - s * uF * u[a]) / alpha;
}

/* Heading dynamics off: turn the body by the smallest rotation that puts its
 * long axis on the field's rotation normal n = B x dB/dt (the sign closest to
 * the present axis). No rotating field -> the axis stays. */
static void snap_axis(Plant *pl, const Drive *d)
{
    double I[N_COILS], dI[N_COILS], B[3], dB[3], n[3], u[3], mh[3];
    coil_currents(pl, d, pl->t, pl->y, I, dI);
    field_at(pl, I, pl->y + Y_P, B, NULL);
    field_at(pl, dI, pl->y + Y_P, dB, NULL);
    cross3(B, dB, n);
    double nn = sqrt(dot3(n, n)), scale = sqrt(dot3(B, B) * dot3(dB, dB));
    if (!(nn > 1e-9 * scale) || nn == 0.0) return;
    body_axes(pl->y + Y_QUAT, u, mh);
    double sgn = (dot3(u, n) >= 0.0) ? 1.0 : -1.0;
    for (int a = 0; a < 3; ++a) n[a] *= sgn / nn;
    double r[4], c[3];
    cross3(u, n, c);
    r[0] = 1.0 + dot3(u, n);             /* half-angle quaternion from u to n */
    r[1] = c[0]; r[2] = c[1]; r[3] = c[2];
    double rn = sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2] + r[3] * r[3]);
    for (int a = 0; a < 4; ++a) r[a] /= rn;
    quat_premultiply(r, pl->y + Y_QUAT);
}

/* Hard walls: the centre stays within +-(tank_half - wall_margin); at contact
 * the outward normal velocity is zeroed. */
static void apply_walls(Plant *pl)
{
    double lim = P(pl, tank_half) - P(pl, wall_margin);
    for (int k = 0; k < 3; ++k) {
        double *p = pl->y + Y_P + k, *v = pl->y + Y_V + k;
        if (*p > lim) { *p = lim; if (*v > 0) *v = 0; }
        if (*p < -lim) { *p = -lim; if (*v < 0) *v = 0; }
    }
}

static void rk4_substep(Plant *pl, const Drive *d, double h)
{
    double k1[NY], k2[NY], k3[NY], k4[NY], tmp[NY];
    double *y = pl->y, t = pl->t;
    derivatives(pl, d, t, y, k1);
    for (int j = 0; j < NY; ++j) tmp[j] = y[j] + 0.5 * h * k1[j];
    derivatives(pl, d, t + 0.5 * h, tmp, k2);
    for (int j = 0; j < NY; ++j) tmp[j] = y[j] + 0.5 * h * k2[j];
    derivatives(pl, d, t + 0.5 * h, tmp, k3);
    for (int j = 0; j < NY; ++j) tmp[j] = y[j] + h * k3[j];
    derivatives(pl, d, t + h, tmp, k4);
    for (int j = 0; j < NY; ++j) y[j] += h / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j]);
}

/* ---------------------------------------------------------------- outputs */

static void update_outputs(Plant *pl, const Drive *d)
{
    double I[N_COILS], dI[N_COILS], B[3], u[3], mh[3];
    coil_currents(pl, d, pl->t, pl->y, I, dI);
    field_at(pl, I, pl->y + Y_P, B, NULL);
    body_axes(pl->y + Y_QUAT, u, mh);
    for (int a = 0; a < 3; ++a) {
        pl->r[R_p_x + a] = pl->y[Y_P + a];
        pl->r[R_v_x + a] = pl->y[Y_V + a];
        pl->r[R_axis_x + a] = u[a];
        pl->r[R_B_x + a] = B[a];
    }
    for (int i = 0; i < N_COILS; ++i) {
        /* Envelope sqrt(I^2 + (omega q)^2): the amplitude of the sinusoidal
         * current; equals the steady-state phasor magnitude once the
         * transient has decayed. */
        double amp;
        if (ON(pl, actuation_lag_on)) {
            double wq = d->omega * pl->y[Y_Q + i];
            amp = sqrt(I[i] * I[i] + wq * wq);
        } else {
            amp = sqrt(d->ire[i] * d->ire[i] + d->iim[i] * d->iim[i]);
        }
        pl->r[R_I_amp_1 + i] = amp;
    }
}

void plant_start(Plant *pl, double t0)
{
    pl->t = t0;
    memset(pl->y, 0, sizeof(pl->y));
    double u[3] = {P(pl, axis0_x), P(pl, axis0_y), P(pl, axis0_z)};
    double un = sqrt(dot3(u, u));
    for (int a = 0; a < 3; ++a) {
        u[a] /= un;
        pl->y[Y_P + a] = pl->r[R_p0_x + a];
    }
    /* Magnet direction: world z (or y if the axis is near z) projected normal to the axis. */
    double ref[3] = {0.0, 0.0, 1.0}, mh[3], c2[3];
    if (fabs(u[2]) > 0.9) { ref[1] = 1.0; ref[2] = 0.0; }
    double ru = dot3(ref, u);
    for (int a = 0; a < 3; ++a) mh[a] = ref[a] - ru * u[a];
    double mn = sqrt(dot3(mh, mh));
    for (int a = 0; a < 3; ++a) mh[a] /= mn;
    cross3(u, mh, c2);
    quat_from_columns(u, mh, c2, pl->y + Y_QUAT);
    normalise_quat(pl->y + Y_QUAT);

    coil_geom_init(&pl->geom, P(pl, coil_turns), P(pl, coil_r_inner), P(pl, coil_r_outer),
                   P(pl, coil_thickness), P(pl, cube_half));
    refresh_field(pl);
    Drive d;
    drive_from_inputs(pl, &d);
    pl->r[R_spin_rate] = 0.0;
    update_outputs(pl, &d);
}

static int state_finite(const Plant *pl)
{
    for (int j = 0; j < NY; ++j)
        if (!isfinite(pl->y[j])) return 0;
    return 1;
}

int plant_step(Plant *pl, double h, char *msg, size_t n)
{
    Drive d;
    drive_from_inputs(pl, &d);
    if (h <= 0.0) {
        update_outputs(pl, &d);
        return 0;
    }
    double t0 = pl->t;
    double n_sub = ceil(h / P(pl, dt_internal) - 1e-9);
    if (n_sub > 1e9) {
        snprintf(msg, n, "step of %g s is too long for dt_internal = %g s", h, P(pl, dt_internal));
        return -1;
    }
    int steps = n_sub < 1.0 ? 1 : (int)n_sub;
    double dt = h / steps;
    pl->y[Y_SPIN] = 0.0;
    for (int a = 0; a < 3; ++a) {
        pl->ext_p0[a] = pl->y[Y_P + a];
        pl->ext_v0[a] = pl->y[Y_V + a];
    }
    for (int k = 0; k < steps; ++k) {
        rk4_substep(pl, &d, dt);
        pl->t = t0 + (k + 1) * dt;
        normalise_quat(pl->y + Y_QUAT);
        apply_walls(pl);
        if (!ON(pl, heading_dynamics_on)) snap_axis(pl, &d);
        double dp[3] = {pl->y[Y_P] - pl->p_ref[0], pl->y[Y_P + 1] - pl->p_ref[1],
                        pl->y[Y_P + 2] - pl->p_ref[2]};
        if (dot3(dp, dp) > REFRESH_DISTANCE * REFRESH_DISTANCE && k + 1 < steps) refresh_field(pl);
    }
    pl->t = t0 + h;
    if (!state_finite(pl)) {
        snprintf(msg, n, "the state became non-finite at t = %g s; reduce dt_internal (now %g s)",
                 pl->t, P(pl, dt_internal));
        return -1;
    }
    refresh_field(pl);
    pl->r[R_spin_rate] = pl->y[Y_SPIN] / (TWO_PI * h);
    update_outputs(pl, &d);
    return 0;
}
