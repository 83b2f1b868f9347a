/* Small 3-vector and quaternion helpers (header-only). Quaternions are (w, x, y, z). */
#ifndef SWIMMER_VEC3_H
#define SWIMMER_VEC3_H

#include <math.h>

static inline double dot3(const double a[3], const double b[3])
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

static inline void cross3(const double a[3], const double b[3], double c[3])
{
    c[0] = a[1] * b[2] - a[2] * b[1];
    c[1] = a[2] * b[0] - a[0] * b[2];
    c[2] = a[0] * b[1] - a[1] * b[0];
}

/* Body long axis u = R e1 and magnet direction mh = R e2 of quaternion q
 * (w, x, y, z), valid for a non-normalised q. */
static inline void body_axes(const double q[4], double u[3], double mh[3])
{
    double w = q[0], x = q[1], y = q[2], z = q[3];
    double s = 2.0 / (w * w + x * x + y * y + z * z);
    u[0] = 1.0 - s * (y * y + z * z); u[1] = s * (x * y + w * z); u[2] = s * (x * z - w * y);
    mh[0] = s * (x * y - w * z); mh[1] = 1.0 - s * (x * x + z * z); mh[2] = s * (y * z + w * x);
}

/* Quaternion of the rotation matrix with columns c0, c1, c2 (Shepperd). */
static inline void quat_from_columns(const double c0[3], const double c1[3], const double c2[3], double q[4])
{
    double m00 = c0[0], m11 = c1[1], m22 = c2[2], tr = m00 + m11 + m22;
    if (tr > 0) {
        double s = 2.0 * sqrt(1.0 + tr);
        q[0] = 0.25 * s; q[1] = (c1[2] - c2[1]) / s; q[2] = (c2[0] - c0[2]) / s; q[3] = (c0[1] - c1[0]) / s;
    } else if (m00 > m11 && m00 > m22) {
        double s = 2.0 * sqrt(1.0 + m00 - m11 - m22);
        q[0] = (c1[2] - c2[1]) / s; q[1] = 0.25 * s; q[2] = (c1[0] + c0[1]) / s; q[3] = (c2[0] + c0[2]) / s;
    } else if (m11 > m22) {
        double s = 2.0 * sqrt(1.0 + m11 - m00 - m22);
        q[0] = (c2[0] - c0[2]) / s; q[1] = (c1[0] + c0[1]) / s; q[2] = 0.25 * s; q[3] = (c2[1] + c1[2]) / s;
    } else {
        double s = 2.0 * sqrt(1.0 + m22 - m00 - m11);
        q[0] = (c0[1] - c1[0]) / s; q[1] = (c2[0] + c0[2]) / s; q[2] = (c2[1] + c1[2]) / s; q[3] = 0.25 * s;
    }
}

/* q <- r (x) q for a unit rotation quaternion r */
static inline void quat_premultiply(const double r[4], double q[4])
{
    double w = r[0] * q[0] - r[1] * q[1] - r[2] * q[2] - r[3] * q[3];
    double x = r[0] * q[1] + r[1] * q[0] + r[2] * q[3] - r[3] * q[2];
    double y = r[0] * q[2] - r[1] * q[3] + r[2] * q[0] + r[3] * q[1];
    double z = r[0] * q[3] + r[1] * q[2] - r[2] * q[1] + r[3] * q[0];
    q[0] = w; q[1] = x; q[2] = y; q[3] = z;
}

static inline void normalise_quat(double *q)
{
    double n = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    for (int a = 0; a < 4; ++a) q[a] /= n;
}

#endif
