/* The plant: six RLC coils, a spiral magnetic swimmer, a water tank.
 *
 * Pure physics, no FMI types. All quantities SI. See README.md for the
 * equations, constants and their sources.
 */
#ifndef SWIMMER_PLANT_H
#define SWIMMER_PLANT_H

#include <stddef.h>

#include "coil_field.h"
#include "variables.h"

/* Integrated state vector layout */
enum {
    Y_Q = 0,        /* coil capacitor charge [C], 6 */
    Y_I = 6,        /* coil current [A], 6 */
    Y_P = 12,       /* position [m], 3 */
    Y_V = 15,       /* velocity [m/s], 3 */
    Y_QUAT = 18,    /* orientation quaternion (w, x, y, z), body -> world, 4 */
    Y_SPIN = 22,    /* accumulated spin angle about the long axis [rad], 1 */
    NY = 23
};

/* Parameter value / effect switch by FMI name */
#define P(pl, name) ((pl)->r[R_##name])
#define ON(pl, name) ((pl)->b[B_##name])

typedef struct {
    double r[N_REAL];        /* every Real variable, indexed by value reference */
    int b[N_BOOL];           /* every Boolean variable */
    double t;                /* current time [s] */
    double y[NY];            /* integrated state */
    CoilGeom geom;           /* coil quadrature (from parameters) */
    double p_ref[3];         /* where G_ref, J_ref were evaluated [m] */
    double G_ref[N_COILS][3];
    double J_ref[N_COILS][3][3];
    double ext_p0[3], ext_v0[3];  /* state at the start of the step [m], [m/s]: where F_ext was evaluated */
} Plant;

/* Name and kind (IN, OUT, PAR, TUN) of every variable, by index */
extern const char *const plant_real_names[N_REAL];
extern const int plant_real_kinds[N_REAL];
extern const char *const plant_bool_names[N_BOOL];
extern const int plant_bool_kinds[N_BOOL];

/* Fill every variable with its default (start) value. */
void plant_defaults(Plant *pl);

/* Check every parameter; on failure write a message naming it and return -1. */
int plant_validate(const Plant *pl, char *msg, size_t n);

/* Check that the inputs are finite; same convention. */
int plant_check_inputs(const Plant *pl, char *msg, size_t n);

/* Set the state at t0 from the parameters and compute the outputs. */
void plant_start(Plant *pl, double t0);

/* Integrate from pl->t over h seconds with the current inputs and update
 * the outputs. Returns -1 with a message when the state stops being finite. */
int plant_step(Plant *pl, double h, char *msg, size_t n);

#endif
