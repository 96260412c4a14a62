// The contact constraints of the neighbour pairs on a GPU: the twins of step/constraints.rs
// (constraint, over the pairs) with model/geometry.rs (min_image, closest_params,
// segment_distance, quat_axis). Layouts: centres as triples, quaternions as w, x, y, z; pairs
// as two int arrays; constraints as rows of 10 doubles (ri, rj, n, phi) beside their i and j.

// Minimum image of one coordinate difference (wrapped coordinates: |c| < l takes one shift).
__device__ double min_image_1(double c, double l) {
    double h = 0.5 * l;
    if (c > h) {
        if (c - l <= h) return c - l;
        return c - l * copysign((double)(long long)(fabs(c / l) + 0.5), c);
    }
    if (c < -h) {
        if (c + l >= -h) return c + l;
        return c - l * copysign((double)(long long)(fabs(c / l) + 0.5), c);
    }
    return c;
}

__device__ double clamp_h(double x, double h) { return x < -h ? -h : (x > h ? h : x); }

// The body axis of quaternion q (w, x, y, z).
__device__ void quat_axis(const double* q, double* p) {
    double w = q[0], x = q[1], y = q[2], z = q[3];
    p[0] = 2.0 * (x * z + w * y);
    p[1] = 2.0 * (y * z - w * x);
    p[2] = 1.0 - 2.0 * (x * x + y * y);
}

// Pair k's constraint if the centerlines are closer than b + margin: writes ri, rj, n, phi to
// row (10 doubles) and returns 1, else returns 0 (row untouched; it may be null).
__device__ int pair_constraint(const double* x, const double* q, int i, int j, double l,
                               double b, double margin, double* row) {
    double pi[3], pj[3], d[3], xi[3], xj[3];
    quat_axis(q + 4 * i, pi);
    quat_axis(q + 4 * j, pj);
    for (int a = 0; a < 3; ++a) {
        xi[a] = x[3 * i + a];
        d[a] = min_image_1(x[3 * j + a] - xi[a], l);
        xj[a] = xi[a] + 1.0 * d[a];
    }
    // closest_params(xi, pi, xj, pj, h = 1/2): two-pass clamping.
    double h = 0.5;
    double r[3] = {xi[0] - xj[0], xi[1] - xj[1], xi[2] - xj[2]};
    double bb = pi[0] * pj[0] + pi[1] * pj[1] + pi[2] * pj[2];
    double c = pi[0] * r[0] + pi[1] * r[1] + pi[2] * r[2];
    double f = pj[0] * r[0] + pj[1] * r[1] + pj[2] * r[2];
    double denom = 1.0 - bb * bb;
    double s;
    if (denom > 1e-12) {
        s = clamp_h((bb * f - c) / denom, h);
    } else {
        double lo = (-c - h) > -h ? (-c - h) : -h;
        double hi = (-c + h) < h ? (-c + h) : h;
        s = lo <= hi ? 0.5 * (lo + hi) : clamp_h(-c, h);
    }
    double t = clamp_h(bb * s + f, h);
    s = clamp_h(bb * t - c, h);
    t = clamp_h(bb * s + f, h);
    double sep[3], ri[3], rj[3];
    for (int a = 0; a < 3; ++a) sep[a] = (xi[a] + s * pi[a]) - (xj[a] + t * pj[a]);
    double dist = sqrt(sep[0] * sep[0] + sep[1] * sep[1] + sep[2] * sep[2]);
    double phi = dist - b;
    if (phi >= margin) return 0;
    if (!row) return 1;
    for (int a = 0; a < 3; ++a) {
        ri[a] = s * pi[a];
        rj[a] = t * pj[a];
    }
    // The separation of the contact points (as constraint(): x_i + r_i - (x_j + r_j)).
    for (int a = 0; a < 3; ++a) sep[a] = (xi[a] + 1.0 * ri[a]) - (xj[a] + 1.0 * rj[a]);
    double nrm[3];
    if (dist > 1e-12) {
        for (int a = 0; a < 3; ++a) nrm[a] = (1.0 / dist) * sep[a];
    } else {
        double dn = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        if (dn < 1e-300) dn = 1e-300;
        for (int a = 0; a < 3; ++a) nrm[a] = (-1.0 / dn) * d[a];
    }
    for (int a = 0; a < 3; ++a) {
        row[a] = ri[a];
        row[3 + a] = rj[a];
        row[6 + a] = nrm[a];
    }
    row[9] = phi;
    return 1;
}

// Whether pair k gets a constraint (1 or 0).
extern "C" __global__ void contact_flag(const double* x, const double* q, const int* first,
                                        const int* second, int* flag, int npairs, double l,
                                        double b, double margin) {
    int k = blockIdx.x * blockDim.x + threadIdx.x;
    if (k >= npairs) return;
    flag[k] = pair_constraint(x, q, first[k], second[k], l, b, margin, 0);
}

// The constraints in pair order at the flags' prefix sums.
extern "C" __global__ void contact_write(const double* x, const double* q, const int* first,
                                         const int* second, const int* flag, const int* at,
                                         int* ci, int* cj, double* rows, int npairs, double l,
                                         double b, double margin) {
    int k = blockIdx.x * blockDim.x + threadIdx.x;
    if (k >= npairs || !flag[k]) return;
    int o = at[k];
    ci[o] = first[k];
    cj[o] = second[k];
    pair_constraint(x, q, first[k], second[k], l, b, margin, rows + 10 * (long long)o);
}
