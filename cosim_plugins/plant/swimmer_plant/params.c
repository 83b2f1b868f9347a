/* Parameter defaults and range checks of the plant. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "plant.h"

const char *const plant_real_names[N_REAL] = {
#define X_NAME(name, kind, def) #name,
    REAL_VARS(X_NAME)
#undef X_NAME
};
const int plant_real_kinds[N_REAL] = {
#define X_KIND(name, kind, def) kind,
    REAL_VARS(X_KIND)
#undef X_KIND
};
const char *const plant_bool_names[N_BOOL] = {
#define X_NAME(name, kind, def) #name,
    BOOL_VARS(X_NAME)
#undef X_NAME
};
const int plant_bool_kinds[N_BOOL] = {
#define X_KIND(name, kind, def) kind,
    BOOL_VARS(X_KIND)
#undef X_KIND
};

void plant_defaults(Plant *pl)
{
    memset(pl, 0, sizeof(*pl));
#define X_DEF_R(name, kind, def) pl->r[R_##name] = (def);
#define X_DEF_B(name, kind, def) pl->b[B_##name] = (def);
    REAL_VARS(X_DEF_R)
    BOOL_VARS(X_DEF_B)
#undef X_DEF_R
#undef X_DEF_B
}

#define REQUIRE(cond, name, why)                                               \
    do {                                                                       \
        if (!(cond)) {                                                         \
            snprintf(msg, n, "parameter %s = %g is out of range: %s", #name,   \
                     pl->r[R_##name], why);                                    \
            return -1;                                                         \
        }                                                                      \
    } while (0)

int plant_validate(const Plant *pl, char *msg, size_t n)
{
    for (int i = 0; i < N_REAL; ++i)
        if ((plant_real_kinds[i] == PAR || plant_real_kinds[i] == TUN) && !isfinite(pl->r[i])) {
            snprintf(msg, n, "parameter %s is not a finite number", plant_real_names[i]);
            return -1;
        }
    REQUIRE(P(pl, mass) > 0, mass, "must be > 0 kg");
    REQUIRE(P(pl, length) > 0, length, "must be > 0 m");
    REQUIRE(P(pl, diameter) > 0, diameter, "must be > 0 m");
    REQUIRE(P(pl, volume) >= 0, volume, "must be >= 0 m^3");
    REQUIRE(P(pl, moment) >= 0, moment, "must be >= 0 A m^2");
    REQUIRE(P(pl, drag_axial) > 0, drag_axial, "must be > 0 N s/m");
    REQUIRE(P(pl, anisotropy_ratio) > 0, anisotropy_ratio, "must be > 0");
    REQUIRE(P(pl, rot_drag_axial) > 0, rot_drag_axial, "must be > 0 N m s");
    REQUIRE(P(pl, rot_drag_perp) > 0, rot_drag_perp, "must be > 0 N m s");
    REQUIRE(P(pl, prop_coeff) >= 0, prop_coeff, "must be >= 0 N s/rad");
    REQUIRE(fabs(P(pl, handedness)) == 1.0, handedness, "must be +1 or -1");
    REQUIRE(P(pl, rho_fluid) >= 0, rho_fluid, "must be >= 0 kg/m^3");
    REQUIRE(P(pl, g) >= 0, g, "must be >= 0 m/s^2");
    REQUIRE(P(pl, tank_half) > 0, tank_half, "must be > 0 m");
    REQUIRE(P(pl, wall_margin) >= 0 && P(pl, wall_margin) < P(pl, tank_half), wall_margin,
            "must be >= 0 and < tank_half");
    REQUIRE(P(pl, coil_turns) > 0, coil_turns, "must be > 0");
    REQUIRE(P(pl, coil_r_inner) > 0, coil_r_inner, "must be > 0 m");
    REQUIRE(P(pl, coil_r_outer) > P(pl, coil_r_inner), coil_r_outer, "must be > coil_r_inner");
    REQUIRE(P(pl, coil_thickness) > 0, coil_thickness, "must be > 0 m");
    REQUIRE(P(pl, cube_half) - 0.5 * P(pl, coil_thickness) > P(pl, tank_half), cube_half,
            "the windings must lie outside the tank (cube_half - coil_thickness/2 > tank_half)");
    REQUIRE(P(pl, R_coil) > 0, R_coil, "must be > 0 ohm");
    REQUIRE(P(pl, L_coil) > 0, L_coil, "must be > 0 H");
    REQUIRE(P(pl, C_coil) > 0, C_coil, "must be > 0 F");
    REQUIRE(P(pl, V_supply_max) > 0, V_supply_max, "must be > 0 V");
    double lim = P(pl, tank_half) - P(pl, wall_margin);
    REQUIRE(fabs(P(pl, p0_x)) <= lim, p0_x, "must lie inside the tank (|p0| <= tank_half - wall_margin)");
    REQUIRE(fabs(P(pl, p0_y)) <= lim, p0_y, "must lie inside the tank (|p0| <= tank_half - wall_margin)");
    REQUIRE(fabs(P(pl, p0_z)) <= lim, p0_z, "must lie inside the tank (|p0| <= tank_half - wall_margin)");
    double a0 = sqrt(P(pl, axis0_x) * P(pl, axis0_x) + P(pl, axis0_y) * P(pl, axis0_y) +
                     P(pl, axis0_z) * P(pl, axis0_z));
    REQUIRE(a0 > 1e-12, axis0_x, "axis0 (axis0_x, axis0_y, axis0_z) must not be the zero vector");
    REQUIRE(P(pl, dt_internal) > 0 && P(pl, dt_internal) <= 0.01, dt_internal,
            "must be in (0, 0.01] s");
    REQUIRE(P(pl, wall_drag_gain) >= 0, wall_drag_gain, "must be >= 0");
    REQUIRE(P(pl, wall_drag_length) > 0, wall_drag_length, "must be > 0 m");
    REQUIRE(P(pl, quad_drag_cd) >= 0, quad_drag_cd, "must be >= 0");
    REQUIRE(P(pl, added_mass_axial) >= 0, added_mass_axial, "must be >= 0");
    REQUIRE(P(pl, added_mass_perp) >= 0, added_mass_perp, "must be >= 0");
    return 0;
}

int plant_check_inputs(const Plant *pl, char *msg, size_t n)
{
    for (int i = 0; i < N_REAL; ++i)
        if (plant_real_kinds[i] == IN && !isfinite(pl->r[i])) {
            snprintf(msg, n, "input %s is not a finite number", plant_real_names[i]);
            return -1;
        }
    return 0;
}
