/* Coil field: circular-loop field with analytic gradient, thick-coil quadrature. */
#include "coil_field.h"

#include <math.h>

#define MU0 (4.0e-7 * M_PI)            /* vacuum permeability [T m/A] */
#define NEAR_AXIS 1.0e-5               /* [m] below this radius use the on-axis expansion */

/* ---- forward-mode dual numbers: value and derivatives d/drho, d/dz ---- */
typedef struct { double v, r, z; } Dual;

static inline Dual d_make(double v, double r, double z) { Dual d = {v, r, z}; return d; }
static inline Dual d_add(Dual a, Dual b) { return d_make(a.v + b.v, a.r + b.r, a.z + b.z); }
static inline Dual d_sub(Dual a, Dual b) { return d_make(a.v - b.v, a.r - b.r, a.z - b.z); }
static inline Dual d_scale(Dual a, double s) { return d_make(a.v * s, a.r * s, a.z * s); }
static inline Dual d_mul(Dual a, Dual b)
{
    return d_make(a.v * b.v, a.r * b.v + a.v * b.r, a.z * b.v + a.v * b.z);
}
static inline Dual d_div(Dual a, Dual b)
{
    double inv = 1.0 / b.v, q = a.v * inv;
    return d_make(q, (a.r - q * b.r) * inv, (a.z - q * b.z) * inv);
}
static inline Dual d_sqrt(Dual a)
{
    double s = sqrt(a.v), h = 0.5 / s;
    return d_make(s, a.r * h, a.z * h);
}

void elliptic_ke(double m, double *K, double *E)
{
    /* Arithmetic-geometric mean: K = pi / (2 a_inf),
     * E = K (1 - sum_n 2^(n-1) c_n^2) with c_0^2 = m. */
    double a = 1.0, b = sqrt(1.0 - m), sum = 0.5 * m, pw = 1.0;
    for (int n = 0; n < 12; ++n) {
        double c = 0.5 * (a - b);
        double an = 0.5 * (a + b);
        b = sqrt(a * b);
        a = an;
        sum += pw * c * c;
        pw *= 2.0;
        if (fabs(c) < 1e-16 * a) break;
    }
    *K = M_PI / (2.0 * a);
    *E = *K * (1.0 - sum);
}

/* Field of one loop of radius a per ampere, in units of mu0/pi, at cylindrical
 * (rho, z), as the six quantities the Cartesian field and gradient need
 * without dividing by rho:
 *   c[0] = B_rho/rho, c[1] = B_z, c[2] = dB_z/dz, c[3] = (dB_z/drho)/rho,
 *   c[4] = (dB_rho/dz)/rho, c[5] = (dB_rho/drho - B_rho/rho)/rho^2.
 * Off axis: the closed form with complete elliptic integrals,
 *   B_z   = [(a^2 - rho^2 - z^2) E + alpha^2 K] / (2 alpha^2 beta),
 *   B_rho = z [(a^2 + rho^2 + z^2) E - alpha^2 K] / (2 alpha^2 beta rho),
 *   alpha^2 = (a - rho)^2 + z^2, beta^2 = (a + rho)^2 + z^2, m = 4 a rho / beta^2,
 * differentiated with dual numbers. */
static void loop_field(double a, double rho_v, double z_v, double c[6])
{
    if (rho_v < NEAR_AXIS) {
        /* Expansion about the axis from the on-axis field F(z) = (pi/2) a^2 s^-1.5,
         * s = a^2 + z^2, with derivatives F1, F2, F3:
         * B_z = F - rho^2 F2 / 4,  B_rho = -rho F1 / 2 + rho^3 F3 / 16. */
        double s = a * a + z_v * z_v, A = 0.5 * M_PI * a * a;
        double s52 = pow(s, -2.5), s72 = s52 / s, s92 = s72 / s;
        double F = A * s52 * s;
        double F1 = -3.0 * A * z_v * s52;
        double F2 = A * (-3.0 * s52 + 15.0 * z_v * z_v * s72);
        double F3 = A * (45.0 * z_v * s72 - 105.0 * z_v * z_v * z_v * s92);
        double r2 = rho_v * rho_v;
        c[0] = -0.5 * F1 + r2 * F3 / 16.0;
        c[1] = F - 0.25 * r2 * F2;
        c[2] = F1 - 0.25 * r2 * F3;
        c[3] = -0.5 * F2;
        c[4] = -0.5 * F2;
        c[5] = F3 / 8.0;
        return;
    }
    Dual rho = d_make(rho_v, 1.0, 0.0), z = d_make(z_v, 0.0, 1.0);
    Dual a2 = d_make(a * a, 0.0, 0.0);
    Dual s = d_add(a2, d_add(d_mul(rho, rho), d_mul(z, z)));
    Dual two_a_rho = d_scale(rho, 2.0 * a);
    Dual al2 = d_sub(s, two_a_rho);
    Dual be2 = d_add(s, two_a_rho);
    Dual be = d_sqrt(be2);
    Dual m = d_div(d_scale(rho, 4.0 * a), be2);

    double K, E, dK, dE;
    elliptic_ke(m.v, &K, &E);
    if (m.v < 1e-5) {           /* series avoids 0/0 in the derivative formulas */
        dK = M_PI / 8.0 + 9.0 * M_PI * m.v / 64.0;
        dE = -M_PI / 8.0 - 3.0 * M_PI * m.v / 64.0;
    } else {
        dK = (E - (1.0 - m.v) * K) / (2.0 * m.v * (1.0 - m.v));
        dE = (E - K) / (2.0 * m.v);
    }
    Dual Kd = d_make(K, dK * m.r, dK * m.z);
    Dual Ed = d_make(E, dE * m.r, dE * m.z);

    Dual den = d_scale(d_mul(al2, be), 2.0);                    /* 2 alpha^2 beta */
    Dual p_bz = d_sub(a2, d_add(d_mul(rho, rho), d_mul(z, z)));  /* a^2 - rho^2 - z^2 */
    Dual bz = d_div(d_add(d_mul(p_bz, Ed), d_mul(al2, Kd)), den);
    Dual q = d_sub(d_mul(s, Ed), d_mul(al2, Kd));                /* s E - alpha^2 K */
    Dual br = d_div(d_mul(z, q), d_mul(den, rho));
    double inv = 1.0 / rho_v;
    c[0] = br.v * inv;
    c[1] = bz.v;
    c[2] = bz.z;
    c[3] = bz.r * inv;
    c[4] = br.z * inv;
    c[5] = (br.r - c[0]) * inv * inv;
}

void coil_geom_init(CoilGeom *g, double turns, double r_inner, double r_outer,
                    double thickness, double cube_half)
{
#if COIL_QUAD == 2
    static const double x[2] = {-0.57735026918962576, 0.57735026918962576};
    static const double w[2] = {1.0, 1.0};
#elif COIL_QUAD == 3
    static const double x[3] = {-0.77459666924148338, 0.0, 0.77459666924148338};
    static const double w[3] = {5.0 / 9.0, 8.0 / 9.0, 5.0 / 9.0};
#endif
    g->cube_half = cube_half;
    for (int i = 0; i < COIL_QUAD; ++i) {
        g->radius[i] = 0.5 * (r_inner + r_outer) + 0.5 * (r_outer - r_inner) * x[i];
        g->offset[i] = 0.5 * thickness * x[i];
    }
    for (int i = 0; i < COIL_QUAD; ++i)
        for (int j = 0; j < COIL_QUAD; ++j)
            g->weight[i][j] = turns * w[i] * w[j] / 4.0;   /* weights sum to turns */
}

void coil_fields(const CoilGeom *g, const double p[3],
                 double G[N_COILS][3], double J[N_COILS][3][3])
{
    for (int i = 0; i < N_COILS; ++i) {
        int k = i / 2, k1 = (k + 1) % 3, k2 = (k + 2) % 3;
        double sign = (i % 2 == 0) ? 1.0 : -1.0;
        double u = p[k1], w = p[k2];                 /* coordinates in the coil plane */
        double zl = p[k] - sign * g->cube_half;      /* axial coordinate from coil centre */
        double rho = sqrt(u * u + w * w);

        double acc[6] = {0, 0, 0, 0, 0, 0};
        for (int a = 0; a < COIL_QUAD; ++a)
            for (int b = 0; b < COIL_QUAD; ++b) {
                double c[6];
                loop_field(g->radius[a], rho, zl - g->offset[b], c);
                for (int n = 0; n < 6; ++n) acc[n] += g->weight[a][b] * c[n];
            }
        double f = MU0 / M_PI;
        double br_rho = f * acc[0], bz = f * acc[1], dz_bz = f * acc[2];
        double dr_bz_rho = f * acc[3], dz_br_rho = f * acc[4], d2 = f * acc[5];

        /* B = B_z e_k + (B_rho/rho)(u e_k1 + w e_k2); J[a][b] = dB_a/dx_b. */
        G[i][k] = bz;
        G[i][k1] = br_rho * u;
        G[i][k2] = br_rho * w;
        J[i][k][k] = dz_bz;
        J[i][k][k1] = dr_bz_rho * u;
        J[i][k][k2] = dr_bz_rho * w;
        J[i][k1][k] = dz_br_rho * u;
        J[i][k2][k] = dz_br_rho * w;
        J[i][k1][k1] = br_rho + d2 * u * u;
        J[i][k2][k2] = br_rho + d2 * w * w;
        J[i][k1][k2] = J[i][k2][k1] = d2 * u * w;
    }
}
