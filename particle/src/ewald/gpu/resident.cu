// The sums with their inputs and outputs on the device (resident.rs): the point cell list of
// the real-space part (the twin of point_cells.rs PointCells::build), moving rows between the
// points' order and the cells', the rods' axes and stresslet values, the stresslet sum's
// assembly (the twin of spectral/mod.rs stresslet_attempt's last pass) and the error model's
// chunked reductions (spectral/estimates.rs estimate_parts). Appended to kernels.cu.

// Wrapped into [0, L) as geometry.rs wrap_position: c - L floor(c / L), 0 where that rounds
// to L.
__device__ double wrap_coordinate(double c, double l) {
    double f = c - l * floor(c / l);
    return f >= l ? 0.0 : f;
}

// Point i's wrapped position, its cell (nc per axis of side L / nc; index (z nc + y) nc + x,
// each clamped to 0..nc - 1 as PointCells::build) and its rank among the cell's points (the
// counts' old value; counts zeroed by the caller).
extern "C" __global__ void point_cell(const double* y, double* wrapped, int* cell, int* rank,
                                      int* count, int n, int nc, double l) {
    int i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= n) return;
    double scale = nc / l;
    int k = 0;
    for (int d = 2; d >= 0; --d) {
        double w = wrap_coordinate(y[3 * i + d], l);
        wrapped[3 * i + d] = w;
        int c = (int)(w * scale);
        if (c < 0) c = 0; // a coordinate that is not finite (the CPU's `as usize` saturates too)
        if (c > nc - 1) c = nc - 1;
        k = k * nc + c;
    }
    cell[i] = k;
    rank[i] = atomicAdd(&count[k], 1);
}

// Rows of width values moved by a permutation idx of 0..n: rows_out[k] = rows_in[idx[k]]
// (scatter 0: the points' values into cell order, idx the cells' members), or
// rows_out[idx[k]] = rows_in[k] (scatter 1: back to the points' order).
extern "C" __global__ void permute_rows(const double* rows_in, const int* idx, double* rows_out,
                                        int n, int width, int scatter) {
    int k = blockIdx.x * blockDim.x + threadIdx.x;
    if (k >= n) return;
    long long from = (long long)idx[k] * width, to = (long long)k * width;
    if (scatter) {
        long long t = from;
        from = to;
        to = t;
    }
    for (int c = 0; c < width; ++c) rows_out[to + c] = rows_in[from + c];
}

// Each cell member's group (its index over the group size).
extern "C" __global__ void member_group(const int* members, int* group, int n, int size) {
    int k = blockIdx.x * blockDim.x + threadIdx.x;
    if (k >= n) return;
    group[k] = members[k] / size;
}

// The body axis of each rod's quaternion (w, x, y, z): geometry.rs quat_axis.
extern "C" __global__ void rod_axes(const double* q, double* p, int n) {
    int r = blockIdx.x * blockDim.x + threadIdx.x;
    if (r >= n) return;
    double w = q[4 * r], x = q[4 * r + 1], y = q[4 * r + 2], z = q[4 * r + 3];
    p[3 * r] = 2.0 * (x * z + w * y);
    p[3 * r + 1] = 2.0 * (y * z - w * x);
    p[3 * r + 2] = 1.0 - 2.0 * (x * x + y * y);
}

// The five trace-free stresslet components sigma (p_i p_j - |p|^2 delta_ij / 3) (xx, yy, xy, xz,
// yz; zz is -(xx + yy)), field-major. The trace's flow is zero (see stresslet_modes), so the
// sum needs no grid for it.
extern "C" __global__ void stresslet_values(const double* p, double sigma, double* vals, int n) {
    int t = blockIdx.x * blockDim.x + threadIdx.x;
    if (t >= n) return;
    double x = p[3 * t], y = p[3 * t + 1], z = p[3 * t + 2];
    double third = (x * x + y * y + z * z) / 3.0;
    vals[t] = sigma * (x * x - third);
    vals[(long long)n + t] = sigma * (y * y - third);
    vals[2 * (long long)n + t] = sigma * (x * y);
    vals[3 * (long long)n + t] = sigma * (x * z);
    vals[4 * (long long)n + t] = sigma * (y * z);
}

// The stresslet real-space sum of stresslets of one strength sigma (stresslet_real's pairs, in
// cell order t) written at the point's own place i = members[t]: velocity at u[3 i..], gradient
// at grad[9 i..] (du_i/dx_m at 3 i + m), weighted strengths at weighted[i]. No copy in cell
// order, no permutation after, no strength per point.
extern "C" __global__ void stresslet_real_points(const double* pos, const double* orient,
                                                 double sigma, const int* group,
                                                 const int* start, const double* table,
                                                 const int* members, double* u, double* grad,
                                                 double* weighted, int npts, int ncell, int nt,
                                                 double l, double cutoff, double inv_h, double xi,
                                                 double r_direct, double r0sq) {
    int t = blockIdx.x * blockDim.x + threadIdx.x;
    if (t >= npts) return;
    StressletPair<false> pair{orient, nullptr, sigma, table, nt, inv_h, xi, r_direct, r0sq, {}};
    for_each_neighbour(t, pos, group, start, npts, ncell, l, cutoff, pair);
    long long i = members[t];
    for (int k = 0; k < 3; ++k) u[3 * i + k] = pair.acc[k];
    for (int k = 0; k < 9; ++k) grad[9 * i + k] = pair.acc[3 + k];
    weighted[i] = pair.acc[12];
}

// The stresslet sum per point t, in place: velocity (real + Fourier) / mu into u (triples, the
// real part in), gradient (real + Fourier - the Fourier part's own term own_c (p p - I/3),
// own_c from sigma) / mu into grad (9 per point, du_i/dx_m at 3 i + m, the real part in), and
// the error model's inputs into parts (4 per point: weighted strengths, |u|^2, weighted
// strengths + sigma^2, |grad u|^2). weighted: the real part's weighted strengths; back: 12
// fields of n values (velocity, then du_i/dx_m at 3 + 3 i + m).
extern "C" __global__ void stresslet_assemble(const double* weighted, const double* back,
                                              const double* p, double* u, double* grad,
                                              double* parts, int n, double sigma,
                                              double own_c, double mu) {
    int t = blockIdx.x * blockDim.x + threadIdx.x;
    if (t >= n) return;
    const double* pt = p + 3 * t;
    double u2 = 0.0, g2 = 0.0;
    for (int i = 0; i < 3; ++i) {
        double v = (u[3 * t + i] + back[(long long)i * n + t]) / mu;
        u[3 * t + i] = v;
        u2 += v * v;
    }
    for (int i = 0; i < 3; ++i) {
        double row = 0.0;
        for (int m = 0; m < 3; ++m) {
            double own = own_c * (pt[i] * pt[m] - (i == m ? 1.0 / 3.0 : 0.0));
            double* g = grad + 9 * (long long)t + 3 * i + m;
            double v = (*g + back[(long long)(3 + 3 * i + m) * n + t] - own) / mu;
            *g = v;
            row += v * v;
        }
        g2 += row;
    }
    double e2 = weighted[t];
    parts[4 * t] = e2;
    parts[4 * t + 1] = u2;
    parts[4 * t + 2] = e2 + sigma * sigma;
    parts[4 * t + 3] = g2;
}

// The error model's reductions (estimates.rs estimate_parts) in the CPU's fixed chunks, for
// the outputs whose inputs are parts' columns (2 o, 2 o + 1) with weights
// w[3 o..3 o + 3] = (a_max, a_2, far): per chunk c and output o, out[4 (nout c + o)..] =
// [max (a_max e + far q), sum (a_2 e + far q), max q, sum q]; one thread per chunk, the
// points in order (the CPU's sums to the last bit).
extern "C" __global__ void estimate_chunks(const double* parts, const double* w, double* out,
                                           int n, int nout, int chunk) {
    // One chunk per block, run by its first thread: the chunks' loads spread over the
    // multiprocessors (a chunk per thread of one block kept them on one).
    if (threadIdx.x != 0) return;
    int c = blockIdx.x;
    int nchunks = (n + chunk - 1) / chunk;
    if (c >= nchunks) return;
    int hi = (c + 1) * chunk < n ? (c + 1) * chunk : n;
    for (int o = 0; o < nout; ++o) {
        double a_max = w[3 * o], a_2 = w[3 * o + 1], far = w[3 * o + 2];
        double acc[4] = {0.0, 0.0, 0.0, 0.0};
        // Sixteen points' inputs at a time (independent loads in flight), folded in order.
        const int B = 16;
        long long t0 = (long long)c * chunk;
        // Whole batches without conditions (straight-line loads, issued together), the tail.
        for (; t0 + B <= hi; t0 += B) {
            double e[B], q[B];
#pragma unroll
            for (int u = 0; u < B; ++u) {
                e[u] = parts[2 * nout * (t0 + u) + 2 * o];
                q[u] = parts[2 * nout * (t0 + u) + 2 * o + 1];
            }
#pragma unroll
            for (int u = 0; u < B; ++u) {
                double m = a_max * e[u] + far * q[u];
                acc[0] = fmax(acc[0], m);
                acc[1] += a_2 * e[u] + far * q[u];
                acc[2] = fmax(acc[2], q[u]);
                acc[3] += q[u];
            }
        }
        for (; t0 < hi; ++t0) {
            double e = parts[2 * nout * t0 + 2 * o], q = parts[2 * nout * t0 + 2 * o + 1];
            double m = a_max * e + far * q;
            acc[0] = fmax(acc[0], m);
            acc[1] += a_2 * e + far * q;
            acc[2] = fmax(acc[2], q);
            acc[3] += q;
        }
        for (int k = 0; k < 4; ++k) out[4 * (nout * c + o) + k] = acc[k];
    }
}

// The dipole level's free velocities (hydro/dipole.rs apply_field): v = U p + u and Jeffery's
// rotation w = p x ((I - p p) (grad u) p), grad at 3 i + m = du_i/dx_m.
extern "C" __global__ void jeffery_velocities(const double* p, const double* u,
                                              const double* grad, double* v, double* w, int n,
                                              double swim) {
    int t = blockIdx.x * blockDim.x + threadIdx.x;
    if (t >= n) return;
    const double* pt = p + 3 * t;
    const double* g = grad + 9 * t;
    double gp[3];
    for (int i = 0; i < 3; ++i) {
        v[3 * t + i] = swim * pt[i] + u[3 * t + i];
        gp[i] = g[3 * i] * pt[0] + g[3 * i + 1] * pt[1] + g[3 * i + 2] * pt[2];
    }
    double c = pt[0] * gp[0] + pt[1] * gp[1] + pt[2] * gp[2];
    double d[3] = {gp[0] - c * pt[0], gp[1] - c * pt[1], gp[2] - c * pt[2]};
    w[3 * t] = pt[1] * d[2] - pt[2] * d[1];
    w[3 * t + 1] = pt[2] * d[0] - pt[0] * d[2];
    w[3 * t + 2] = pt[0] * d[1] - pt[1] * d[0];
}

// ---------------------------------------------------------------------------------------------
// The explicit slender-body level (hydro/explicit.rs): nodes, the RPY sum's own-group
// corrections (spectral/real_space.rs rpy_assemble) and the rods' rigid-body velocities
// (hydro/slender.rs flow_velocities).

// Minimum image of a difference (geometry.rs min_image).
__device__ double min_image_any(double c, double l) {
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

// Node k = r m + j of rod r: position x_r + s_j p_r (triples), the weighted force of the
// isolated swimmer's density (c sign(s_j) p_r) w_j as triples and field-major (3 fields of
// n m values).
extern "C" __global__ void node_values(const double* x, const double* p, const double* s,
                                       const double* w, double* nodes, double* force,
                                       double* fields, int n, int m, double c) {
    int k = blockIdx.x * blockDim.x + threadIdx.x;
    if (k >= n * m) return;
    int r = k / m, j = k % m;
    double sign = copysign(1.0, s[j]); // f64::signum
    long long nm = (long long)n * m;
    for (int d = 0; d < 3; ++d) {
        nodes[3 * k + d] = x[3 * r + d] + s[j] * p[3 * r + d];
        double f = c * sign * p[3 * r + d] * w[j];
        force[3 * k + d] = f;
        fields[d * nm + k] = f;
    }
}

// The free Fourier part of the RPY tensor (ewald/kernels.rs rpy_fourier_free): (A, B) at r, its
// limit (A_F(0), 0) at r = 0.
__device__ void rpy_fourier_free(double r, double xi, double a, double* ab) {
    const double PI = 3.14159265358979323846;
    const double PI_3_2 = 5.568327996831708;
    double a2 = a * a, x2 = xi * xi;
    if (r == 0.0) {
        ab[0] = xi * (7.0 * a2 * a2 * x2 * x2 - 10.0 * a2 * x2 + 9.0) / (18.0 * PI_3_2);
        ab[1] = 0.0;
        return;
    }
    double r3 = r * r * r;
    double af = (1.0 / r + 2.0 * a2 / (3.0 * r3)) / (8.0 * PI);
    double bf = (1.0 / r - 2.0 * a2 / r3) / (8.0 * PI);
    double r2 = r * r;
    double ec = erfc(xi * r);
    double e = exp(-x2 * r2);
    double x4 = x2 * x2;
    double a4x4 = a2 * a2 * x4, x6 = x4 * x2, x8 = x4 * x4;
    double a4 = a2 * a2;
    double poly_a = -4.0 * a4 * r2 * r2 * x8 + 22.0 * a4 * r2 * x6 - 14.0 * a4x4 -
                    12.0 * a2 * r2 * x4 + 24.0 * a2 * x2 - 9.0;
    double poly_b =
        4.0 * a4 * r2 * r2 * x8 - 18.0 * a4 * r2 * x6 + 12.0 * a2 * r2 * x4 - 12.0 * a2 * x2 + 9.0;
    double g = xi * e / PI_3_2;
    double cc = ec / (PI * r * r2);
    double ar = cc * (r2 / 8.0 + a2 / 12.0) + g * (a2 / (6.0 * r2) + poly_a / 36.0);
    double br = cc * (r2 / 8.0 - a2 / 4.0) + g * (-a2 / (2.0 * r2) + poly_b / 36.0);
    ab[0] = af - ar;
    ab[1] = bf - br;
}

// The RPY sum per point t: real (4 per point, points' order) plus the Fourier part (back: 3
// fields of n), less the free Fourier part of every point of its own group (itself included),
// over mu into u (triples); the error model's inputs into parts (weighted strengths with the
// own group's, |u|^2).
extern "C" __global__ void rpy_assemble(const double* real, const double* back,
                                        const double* pts, const double* force, double* u,
                                        double* parts, int n, int g, double l, double xi,
                                        double a, double r0sq, double mu) {
    int t = blockIdx.x * blockDim.x + threadIdx.x;
    if (t >= n) return;
    const double* rt = real + 4 * (long long)t;
    double ut[3];
    for (int d = 0; d < 3; ++d) ut[d] = rt[d] + back[(long long)d * n + t];
    double e2 = rt[3];
    int base = (t / g) * g;
    for (int j = base; j < base + g; ++j) {
        double r[3];
        for (int d = 0; d < 3; ++d) r[d] = min_image_any(pts[3 * t + d] - pts[3 * j + d], l);
        const double* f = force + 3 * j;
        double r2 = r[0] * r[0] + r[1] * r[1] + r[2] * r[2];
        double rn = sqrt(r2);
        double rh[3] = {0.0, 0.0, 0.0};
        if (rn > 0.0)
            for (int d = 0; d < 3; ++d) rh[d] = r[d] / rn;
        double ab[2];
        rpy_fourier_free(rn, xi, a, ab);
        double s = ab[1] * (rh[0] * f[0] + rh[1] * f[1] + rh[2] * f[2]);
        for (int d = 0; d < 3; ++d) ut[d] -= ab[0] * f[d] + s * rh[d];
        e2 += r0sq / (r0sq + r2) * (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]);
    }
    double u2 = 0.0;
    for (int d = 0; d < 3; ++d) {
        double v = ut[d] / mu;
        u[3 * t + d] = v;
        u2 += v * v;
    }
    parts[2 * t] = e2;
    parts[2 * t + 1] = u2;
}

// The rods' velocities from the flow u at their m nodes each (hydro/slender.rs
// flow_velocities, with explicit.rs's swimming): v = U p + [u]_l / l,
// w = p x (12 / l^3)(I - p p)[s u]_l, [.]_l the rule (s, w).
extern "C" __global__ void rod_flow_velocities(const double* p, const double* u,
                                               const double* s, const double* w, double* v,
                                               double* omega, int n, int m, double swim,
                                               double rod) {
    int r = blockIdx.x * blockDim.x + threadIdx.x;
    if (r >= n) return;
    double a[3] = {0.0, 0.0, 0.0}, b[3] = {0.0, 0.0, 0.0};
    for (int j = 0; j < m; ++j) {
        const double* uj = u + 3 * ((long long)r * m + j);
        for (int d = 0; d < 3; ++d) {
            a[d] += w[j] * uj[d];
            b[d] += w[j] * s[j] * uj[d];
        }
    }
    const double* pn = p + 3 * r;
    double c = pn[0] * b[0] + pn[1] * b[1] + pn[2] * b[2];
    double pdot[3];
    for (int d = 0; d < 3; ++d) {
        pdot[d] = 12.0 / (rod * rod * rod) * (b[d] - c * pn[d]);
        v[3 * r + d] = swim * pn[d] + a[d] / rod;
    }
    omega[3 * r] = pn[1] * pdot[2] - pn[2] * pdot[1];
    omega[3 * r + 1] = pn[2] * pdot[0] - pn[0] * pdot[2];
    omega[3 * r + 2] = pn[0] * pdot[1] - pn[1] * pdot[0];
}
