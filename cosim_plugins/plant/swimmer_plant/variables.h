/* Every FMU variable in one place (X-macro lists).
 *
 * Real variables: value reference = position in REAL_VARS (0, 1, 2, ...).
 * Boolean variables: value reference = BOOL_VR_BASE + position in BOOL_VARS.
 * modelDescription.xml lists the same names, value references and start
 * values; tests/plant/test_fmu_interface.py checks that they agree.
 *
 * X(name, kind, default) with kind: IN (input), OUT (output), PAR (fixed
 * parameter), TUN (tunable parameter). Units and sources: README.md.
 */
#ifndef SWIMMER_VARIABLES_H
#define SWIMMER_VARIABLES_H

#define REAL_VARS(X) \
    /* inputs: coil voltage amplitude [V], phase [rad], drive frequency [Hz] */ \
    X(V_amp_1, IN, 0.0) X(V_amp_2, IN, 0.0) X(V_amp_3, IN, 0.0) \
    X(V_amp_4, IN, 0.0) X(V_amp_5, IN, 0.0) X(V_amp_6, IN, 0.0) \
    X(V_phase_1, IN, 0.0) X(V_phase_2, IN, 0.0) X(V_phase_3, IN, 0.0) \
    X(V_phase_4, IN, 0.0) X(V_phase_5, IN, 0.0) X(V_phase_6, IN, 0.0) \
    X(freq, IN, 0.0) \
    /* outputs */ \
    X(p_x, OUT, 0.0) X(p_y, OUT, 0.0) X(p_z, OUT, 0.0) \
    X(v_x, OUT, 0.0) X(v_y, OUT, 0.0) X(v_z, OUT, 0.0) \
    X(axis_x, OUT, 1.0) X(axis_y, OUT, 0.0) X(axis_z, OUT, 0.0) \
    X(spin_rate, OUT, 0.0) \
    X(I_amp_1, OUT, 0.0) X(I_amp_2, OUT, 0.0) X(I_amp_3, OUT, 0.0) \
    X(I_amp_4, OUT, 0.0) X(I_amp_5, OUT, 0.0) X(I_amp_6, OUT, 0.0) \
    X(B_x, OUT, 0.0) X(B_y, OUT, 0.0) X(B_z, OUT, 0.0) \
    /* swimmer */ \
    X(mass, PAR, 12.4e-6) \
    X(length, PAR, 6.0e-3) \
    X(diameter, PAR, 2.5e-3) \
    X(volume, PAR, 12.38e-9) \
    X(moment, PAR, 1.0e-4) \
    X(drag_axial, PAR, 8.0e-5) \
    X(anisotropy_ratio, PAR, 1.5) \
    X(rot_drag_axial, PAR, 2.0e-9) \
    X(rot_drag_perp, PAR, 1.0e-8) \
    X(prop_coeff, PAR, 3.2e-8) \
    X(handedness, PAR, 1.0) \
    /* fluid and tank */ \
    X(rho_fluid, PAR, 998.2) \
    X(g, PAR, 9.81) \
    X(tank_half, PAR, 0.075) \
    X(wall_margin, PAR, 1.25e-3) \
    /* coils */ \
    X(coil_turns, PAR, 795.0) \
    X(coil_r_inner, PAR, 0.180) \
    X(coil_r_outer, PAR, 0.215) \
    X(coil_thickness, PAR, 0.040) \
    X(cube_half, PAR, 0.150) \
    X(R_coil, PAR, 12.9) \
    X(L_coil, PAR, 0.411) \
    X(C_coil, PAR, 430.0e-6) \
    X(V_supply_max, PAR, 40.0) \
    /* initial state */ \
    X(p0_x, PAR, 0.0) X(p0_y, PAR, 0.0) X(p0_z, PAR, 0.0) \
    X(axis0_x, PAR, 1.0) X(axis0_y, PAR, 0.0) X(axis0_z, PAR, 0.0) \
    /* numerics */ \
    X(dt_internal, PAR, 1.0e-3) \
    /* effect magnitudes */ \
    X(flow_x, TUN, 0.002) X(flow_y, TUN, 0.0) X(flow_z, TUN, 0.0) \
    X(wall_drag_gain, PAR, 2.0) \
    X(wall_drag_length, PAR, 2.5e-3) \
    X(gradient_force_scale, PAR, 1.0) \
    X(quad_drag_cd, PAR, 1.0) \
    X(added_mass_axial, PAR, 0.165) X(added_mass_perp, PAR, 0.752) \
    /* external force [N], tank frame, inputs appended so the value references above stay: */ \
    /* F = F_ext + F_ext_dp (p - p_0) + F_ext_dv (v - v_0), p_0 and v_0 the state at the */ \
    /* start of the step; F_ext_dp_ab = dF_a/dp_b [N/m], F_ext_dv_ab = dF_a/dv_b [N s/m] */ \
    X(F_ext_x, IN, 0.0) X(F_ext_y, IN, 0.0) X(F_ext_z, IN, 0.0) \
    X(F_ext_dp_xx, IN, 0.0) X(F_ext_dp_xy, IN, 0.0) X(F_ext_dp_xz, IN, 0.0) \
    X(F_ext_dp_yx, IN, 0.0) X(F_ext_dp_yy, IN, 0.0) X(F_ext_dp_yz, IN, 0.0) \
    X(F_ext_dp_zx, IN, 0.0) X(F_ext_dp_zy, IN, 0.0) X(F_ext_dp_zz, IN, 0.0) \
    X(F_ext_dv_xx, IN, 0.0) X(F_ext_dv_xy, IN, 0.0) X(F_ext_dv_xz, IN, 0.0) \
    X(F_ext_dv_yx, IN, 0.0) X(F_ext_dv_yy, IN, 0.0) X(F_ext_dv_yz, IN, 0.0) \
    X(F_ext_dv_zx, IN, 0.0) X(F_ext_dv_zy, IN, 0.0) X(F_ext_dv_zz, IN, 0.0)

#define BOOL_VARS(X) \
    X(background_flow_on, TUN, 0) \
    X(wall_drag_on, PAR, 0) \
    X(gradient_force_on, PAR, 1) \
    X(quadratic_drag_on, PAR, 0) \
    X(anisotropic_drag_on, PAR, 1) \
    X(actuation_lag_on, PAR, 1) \
    X(heading_dynamics_on, PAR, 1) \
    X(added_mass_on, PAR, 0)

#define BOOL_VR_BASE 1000

#define X_ENUM_R(name, kind, def) R_##name,
#define X_ENUM_B(name, kind, def) B_##name,
enum { REAL_VARS(X_ENUM_R) N_REAL };
enum { BOOL_VARS(X_ENUM_B) N_BOOL };
#undef X_ENUM_R
#undef X_ENUM_B

/* variable kinds */
enum { IN, OUT, PAR, TUN };

#endif
