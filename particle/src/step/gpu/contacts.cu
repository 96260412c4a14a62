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
__device__ __forceinline__ int pair_constraint(const double* x, const double* q, int i, int j,
                                               double l, double b, double margin, double* row) {
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

// --- The contact solver's products and reductions (step/contact.rs, BBPGD) -------------------
// Per-rod lists of constraints: entries 2 a + side (side 0: the rod is constraint a's i, 1: its
// j), each rod's in increasing a (the CPU's constraint order).

extern "C" __global__ void solver_index_count(const int* ci, const int* cj, int* counts, int m) {
    int k = blockIdx.x * blockDim.x + threadIdx.x;
    if (k >= m) return;
    atomicAdd(&counts[ci[k]], 1);
    atomicAdd(&counts[cj[k]], 1);
}

extern "C" __global__ void solver_index_scatter(const int* ci, const int* cj, const int* start,
                                                int* fill, int* entries, int m) {
    int k = blockIdx.x * blockDim.x + threadIdx.x;
    if (k >= m) return;
    entries[start[ci[k]] + atomicAdd(&fill[ci[k]], 1)] = 2 * k;
    entries[start[cj[k]] + atomicAdd(&fill[cj[k]], 1)] = 2 * k + 1;
}

extern "C" __global__ void solver_index_order(const int* start, int* entries, int n) {
    int r = blockIdx.x * blockDim.x + threadIdx.x;
    if (r >= n) return;
    sort_ints(entries + start[r], start[r + 1] - start[r]);
}

__device__ void cross3(const double* a, const double* b, double* c) {
    c[0] = a[1] * b[2] - a[2] * b[1];
    c[1] = a[2] * b[0] - a[0] * b[2];
    c[2] = a[0] * b[1] - a[1] * b[0];
}

// Each rod's axis from its quaternion.
extern "C" __global__ void solver_axes(const double* q, double* p, int n) {
    int r = blockIdx.x * blockDim.x + threadIdx.x;
    if (r >= n) return;
    quat_axis(q + 4 * r, p + 3 * r);
}

// Each rod's velocity (v, w: 6 values) under the contact forces of multipliers lam through the
// local drag (trans (I + p p), rot (I - p p)), and the force and torque themselves (ft).
extern "C" __global__ void solver_rods(const double* p, const int* start, const int* entries,
                                       const double* rows, const double* lam, double* vel,
                                       double* ft, int n, double trans, double rot) {
    int r = blockIdx.x * blockDim.x + threadIdx.x;
    if (r >= n) return;
    double f[3] = {0.0, 0.0, 0.0}, t[3] = {0.0, 0.0, 0.0};
    for (int e = start[r]; e < start[r + 1]; ++e) {
        int a = entries[e] >> 1;
        double side = (entries[e] & 1) ? -1.0 : 1.0;
        const double* row = rows + 10 * (long long)a;
        double sl = side * lam[a];
        double fa[3] = {sl * row[6], sl * row[7], sl * row[8]};
        double tq[3];
        cross3(side > 0.0 ? row : row + 3, fa, tq);
        for (int d = 0; d < 3; ++d) {
            f[d] = f[d] + 1.0 * fa[d];
            t[d] = t[d] + 1.0 * tq[d];
        }
    }
    const double* pr = p + 3 * r;
    double pf = pr[0] * f[0] + pr[1] * f[1] + pr[2] * f[2];
    double pt = pr[0] * t[0] + pr[1] * t[1] + pr[2] * t[2];
    for (int d = 0; d < 3; ++d) {
        vel[6 * r + d] = trans * (f[d] + pf * pr[d]);
        vel[6 * r + 3 + d] = rot * (t[d] - pt * pr[d]);
        ft[6 * r + d] = f[d];
        ft[6 * r + 3 + d] = t[d];
    }
}

// out[k] = dt n.(v_i + w_i x r_i - v_j - w_j x r_j) + shift[k] (shift 0 where has_shift is 0),
// velocities as 6 values per rod (v, w) in vel.
extern "C" __global__ void solver_constraints(const double* rows, const int* ci, const int* cj,
                                              const double* vel, const double* shift,
                                              double* out, int m, double dt, int has_shift) {
    int k = blockIdx.x * blockDim.x + threadIdx.x;
    if (k >= m) return;
    const double* row = rows + 10 * (long long)k;
    const double* a = vel + 6 * ci[k];
    const double* b = vel + 6 * cj[k];
    double ca[3], cb[3], d[3];
    cross3(a + 3, row, ca);
    cross3(b + 3, row + 3, cb);
    for (int e = 0; e < 3; ++e) d[e] = (a[e] + 1.0 * ca[e]) - (b[e] + 1.0 * cb[e]);
    double s = has_shift ? shift[k] : 0.0;
    out[k] = dt * (row[6] * d[0] + row[7] * d[1] + row[8] * d[2]) + s;
}

// q[k] = phi_k + dt n.(free velocity difference at the contact points), free velocities as
// triples v and w.
extern "C" __global__ void solver_q(const double* rows, const int* ci, const int* cj,
                                    const double* v, const double* w, double* q, int m,
                                    double dt) {
    int k = blockIdx.x * blockDim.x + threadIdx.x;
    if (k >= m) return;
    const double* row = rows + 10 * (long long)k;
    int i = ci[k], j = cj[k];
    double ca[3], cb[3], d[3];
    cross3(w + 3 * i, row, ca);
    cross3(w + 3 * j, row + 3, cb);
    for (int e = 0; e < 3; ++e) d[e] = (v[3 * i + e] + 1.0 * ca[e]) - (v[3 * j + e] + 1.0 * cb[e]);
    q[k] = row[9] + dt * (row[6] * d[0] + row[7] * d[1] + row[8] * d[2]);
}

// lam_new = max(lam - alpha g, 0).
extern "C" __global__ void solver_project(const double* lam, const double* g, double* lam_new,
                                          int m, double alpha) {
    int k = blockIdx.x * blockDim.x + threadIdx.x;
    if (k >= m) return;
    lam_new[k] = fmax(lam[k] - alpha * g[k], 0.0);
}

// The projected gradient of the first step: g where lam > 0 or g < 0, else 0.
extern "C" __global__ void solver_gp(const double* lam, const double* g, double* gp, int m) {
    int k = blockIdx.x * blockDim.x + threadIdx.x;
    if (k >= m) return;
    gp[k] = (lam[k] > 0.0 || g[k] < 0.0) ? g[k] : 0.0;
}

// The sequential reductions below fold their chunk in order, as the CPU does. One block per
// chunk: its threads compute the terms of blockDim.x consecutive elements at a time into shared
// memory (their loads in flight together, across the block), then its first thread folds them
// in order; the additions' order, and so every bit, is the one-thread fold's. (One thread per
// chunk loading and folding alone took 0.23 ms per call at L/l = 100: the fold waited on each
// batch's loads and on its own arithmetic.) Each kernel is launched with one block per chunk
// (`chunk` elements, the CPU's chunk size).
#define FOLD_THREADS 256

// Per chunk c of `chunk` constraints, in order: max |min(lam_new, g_new)|, |s|^2, s.y, |y|^2
// with s = lam_new - lam, y = g_new - g (4 values at 4 c): fused_stats' partials.
extern "C" __global__ void solver_stats(const double* lam, const double* lam_new,
                                        const double* g, const double* g_new, double* partial,
                                        int m, int chunk) {
    __shared__ double sh_s[FOLD_THREADS], sh_y[FOLD_THREADS], sh_mn[FOLD_THREADS];
    int c = blockIdx.x, t = threadIdx.x;
    if ((long long)c * chunk >= m) return; // the whole block
    int hi = (c + 1) * chunk < m ? (c + 1) * chunk : m;
    double a0 = 0.0, a1 = 0.0, a2 = 0.0, a3 = 0.0;
    for (int k0 = c * chunk; k0 < hi; k0 += FOLD_THREADS) {
        int k = k0 + t;
        if (k < hi) {
            double ln = lam_new[k], gn = g_new[k];
            sh_s[t] = ln - lam[k];
            sh_y[t] = gn - g[k];
            sh_mn[t] = fabs(fmin(ln, gn));
        }
        __syncthreads();
        if (t == 0) {
            int len = hi - k0 < FOLD_THREADS ? hi - k0 : FOLD_THREADS;
            for (int u = 0; u < len; ++u) {
                double su = sh_s[u], yu = sh_y[u];
                a0 = fmax(a0, sh_mn[u]);
                a1 += su * su;
                a2 += su * yu;
                a3 += yu * yu;
            }
        }
        __syncthreads();
    }
    if (t == 0) {
        partial[4 * c] = a0;
        partial[4 * c + 1] = a1;
        partial[4 * c + 2] = a2;
        partial[4 * c + 3] = a3;
    }
}

// APGD's per chunk c, in order: max |min(x_new, g_new)| and the sum of (y - x_new)(x_new - x)
// (2 values at 2 c): apgd_stats' partials.
extern "C" __global__ void solver_apgd_stats(const double* x, const double* x_new,
                                             const double* y, const double* g_new,
                                             double* partial, int m, int chunk) {
    __shared__ double sh_mn[FOLD_THREADS], sh_up[FOLD_THREADS];
    int c = blockIdx.x, t = threadIdx.x;
    if ((long long)c * chunk >= m) return; // the whole block
    int hi = (c + 1) * chunk < m ? (c + 1) * chunk : m;
    double a0 = 0.0, a1 = 0.0;
    for (int k0 = c * chunk; k0 < hi; k0 += FOLD_THREADS) {
        int k = k0 + t;
        if (k < hi) {
            double xn = x_new[k];
            sh_mn[t] = fabs(fmin(xn, g_new[k]));
            sh_up[t] = (y[k] - xn) * (xn - x[k]);
        }
        __syncthreads();
        if (t == 0) {
            int len = hi - k0 < FOLD_THREADS ? hi - k0 : FOLD_THREADS;
            for (int u = 0; u < len; ++u) {
                a0 = fmax(a0, sh_mn[u]);
                a1 += sh_up[u];
            }
        }
        __syncthreads();
    }
    if (t == 0) {
        partial[2 * c] = a0;
        partial[2 * c + 1] = a1;
    }
}

// APGD's extrapolated point and its gradient: y = x_new + beta (x_new - x), gy likewise from
// the gradients (A is linear).
extern "C" __global__ void solver_extrapolate(const double* x_new, const double* x,
                                              const double* g_new, const double* g, double* y,
                                              double* gy, int m, double beta) {
    int k = blockIdx.x * blockDim.x + threadIdx.x;
    if (k >= m) return;
    y[k] = x_new[k] + beta * (x_new[k] - x[k]);
    gy[k] = g_new[k] + beta * (g_new[k] - g[k]);
}

// out = a / d: the power iteration's normalisation.
extern "C" __global__ void solver_scale(const double* a, double* out, int m, double d) {
    int k = blockIdx.x * blockDim.x + threadIdx.x;
    if (k >= m) return;
    out[k] = a[k] / d;
}

// Per chunk: the sums of a a and a b in order from -0.0 (det_sum's partials), at 2 c.
extern "C" __global__ void solver_dots(const double* a, const double* b, double* partial, int m,
                                       int chunk) {
    __shared__ double sh_a[FOLD_THREADS], sh_b[FOLD_THREADS];
    int c = blockIdx.x, t = threadIdx.x;
    if ((long long)c * chunk >= m) return; // the whole block
    int hi = (c + 1) * chunk < m ? (c + 1) * chunk : m;
    double aa = -0.0, ab = -0.0;
    for (int k0 = c * chunk; k0 < hi; k0 += FOLD_THREADS) {
        int k = k0 + t;
        if (k < hi) {
            sh_a[t] = a[k];
            sh_b[t] = b[k];
        }
        __syncthreads();
        if (t == 0) {
            int len = hi - k0 < FOLD_THREADS ? hi - k0 : FOLD_THREADS;
            for (int u = 0; u < len; ++u) {
                double x = sh_a[u];
                aa += x * x;
                ab += x * sh_b[u];
            }
        }
        __syncthreads();
    }
    if (t == 0) {
        partial[2 * c] = aa;
        partial[2 * c + 1] = ab;
    }
}
