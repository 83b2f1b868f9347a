/* Field of the six thick coils and its spatial gradient, per ampere.
 *
 * Each coil is a circular winding of rectangular cross-section (radii
 * r_inner..r_outer, axial thickness t) centred on a cube face at distance
 * cube_half from the origin. Its field is the exact circular-loop field
 * (complete elliptic integrals) integrated over the cross-section with
 * Gauss-Legendre quadrature; the gradient is differentiated analytically
 * (forward-mode dual numbers), so G and dG/dx are consistent.
 *
 * Coil index i = 0..5 <-> faces +x, -x, +y, -y, +z, -z. Positive current
 * makes field along +x, +x, +y, +y, +z, +z at the origin.
 */
#ifndef SWIMMER_COIL_FIELD_H
#define SWIMMER_COIL_FIELD_H

#define N_COILS 6
#define COIL_QUAD 2 /* Gauss points per direction (radial and axial) */

typedef struct {
    double cube_half;                       /* [m] coil centre distance from origin */
    double radius[COIL_QUAD];               /* [m] quadrature radii */
    double offset[COIL_QUAD];               /* [m] quadrature axial offsets */
    double weight[COIL_QUAD][COIL_QUAD];    /* turns carried by each node */
} CoilGeom;

/* Set up the quadrature of one coil (all six are identical). */
void coil_geom_init(CoilGeom *g, double turns, double r_inner, double r_outer,
                    double thickness, double cube_half);

/* Field per ampere G[i][a] = B_a / I_i [T/A] and its gradient
 * J[i][a][b] = dG[i][a]/dx_b [T/(A m)] at position p [m]. */
void coil_fields(const CoilGeom *g, const double p[3],
                 double G[N_COILS][3], double J[N_COILS][3][3]);

/* Complete elliptic integrals K(m), E(m) of parameter m = k^2 (0 <= m < 1). */
void elliptic_ke(double m, double *K, double *E);

#endif
