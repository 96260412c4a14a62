// The slender-body level's (P4) on the device: its operator around the resident RPY sum and the
// vector operations of GMRES (hydro/gpu/mod.rs). Every kernel does the CPU's arithmetic in the
// CPU's order (hydro/slender.rs, hydro/gmres.rs; NVRTC compiles without contraction into fused
// multiply-adds), so with the same products the device's iterates are the CPU's bits.
//
// Layout: a density or residual vector is 3 m n values ([rod][node][xyz]); the Arnoldi basis is
// a buffer per vector, made as GMRES reaches it.

// Node k = r m + j of rod r at x_r + s_j p_r (slender.rs's node_positions).
extern "C" __global__ void slender_nodes(const double* x, const double* p, const double* s,
                                         double* nodes, int n, int m) {
    int k = blockIdx.x * blockDim.x + threadIdx.x;
    if (k >= n * m) return;
    int r = k / m, j = k % m;
    for (int d = 0; d < 3; ++d) nodes[3 * k + d] = x[3 * r + d] + s[j] * p[3 * r + d];
}

// (P4)'s right-hand side, entry k = 3 (r m + j) + d: swimming, plus with has_ft the contact
// force and torque of rod r (ft: 6 values per rod) (SlenderBody::rhs).
extern "C" __global__ void slender_rhs(const double* p, const double* ft, const double* s,
                                       double* rhs, int n, int m, double c, double l,
                                       int has_ft) {
    int k = blockIdx.x * blockDim.x + threadIdx.x;
    if (k >= 3 * n * m) return;
    int r = k / (3 * m), j = (k / 3) % m, d = k % 3;
    double swim = c * copysign(1.0, s[j]) * p[3 * r + d];
    if (!has_ft) {
        rhs[k] = swim;
        return;
    }
    const double* f = ft + 6 * r;
    const double* t = f + 3;
    const double* pr = p + 3 * r;
    // Component d of t x p (no array indexed by d: it would keep a stack, see kernels.cu's
    // gather_point).
    int d1 = d == 2 ? 0 : d + 1, d2 = d == 0 ? 2 : d - 1;
    double txp = t[d1] * pr[d2] - t[d2] * pr[d1];
    rhs[k] = swim + f[d] / l + 12.0 * s[j] / (l * l * l) * txp;
}

// The RPY sum's inputs from the density f: node k's force f_k w_(k mod m) as triples and
// field-major (P4::flow's weighted forces).
extern "C" __global__ void slender_weighted(const double* f, const double* w, double* force,
                                            double* fields, int npts, int m) {
    int k = blockIdx.x * blockDim.x + threadIdx.x;
    if (k >= npts) return;
    double wk = w[k % m];
    for (int d = 0; d < 3; ++d) {
        double v = f[3LL * k + d] * wk;
        force[3 * k + d] = v;
        fields[(long long)d * npts + k] = v;
    }
}

// p . v, the CPU's order.
__device__ double p4_dot(const double* p, const double* v) {
    return p[0] * v[0] + p[1] * v[1] + p[2] * v[2];
}

// [u]_l and [s u]_l of one rod's node values u (slender.rs's moments).
__device__ void rod_moments(const double* u, const double* s, const double* w, int m, double* a,
                            double* b) {
    for (int d = 0; d < 3; ++d) a[d] = b[d] = 0.0;
    for (int j = 0; j < m; ++j) {
        for (int d = 0; d < 3; ++d) {
            a[d] += w[j] * u[3 * j + d];
            b[d] += w[j] * s[j] * u[3 * j + d];
        }
    }
}

// The operator of (P4) on rod r (one thread each): out = f + (I - pp/2) u_j / e
// - (I - pp/2)[u]_l / (e l) - 12 s_j / (e l^3) (I - pp)[s u]_l, from the density f and the
// flow u it induces at the nodes (P4::apply).
extern "C" __global__ void slender_p4(const double* f, const double* u, const double* p,
                                      const double* s, const double* w, double* out, int n,
                                      int m, double e, double l) {
    int r = blockIdx.x * blockDim.x + threadIdx.x;
    if (r >= n) return;
    long long base = 3LL * r * m;
    const double* ur = u + base;
    const double* fr = f + base;
    double* o = out + base;
    double pn[3] = {p[3 * r], p[3 * r + 1], p[3 * r + 2]};
    double a[3], b[3];
    rod_moments(ur, s, w, m, a, b);
    double ca = 0.5 * p4_dot(pn, a), cb = p4_dot(pn, b);
    double hb[3], ps[3];
    for (int d = 0; d < 3; ++d) {
        hb[d] = a[d] - ca * pn[d];
        ps[d] = b[d] - cb * pn[d];
    }
    for (int j = 0; j < m; ++j) {
        const double* uj = ur + 3 * j;
        double cu = 0.5 * p4_dot(pn, uj);
        double c = 12.0 * s[j] / (e * l * l * l);
        for (int d = 0; d < 3; ++d) {
            double hj = uj[d] - cu * pn[d];
            o[3 * j + d] = fr[3 * j + d] + hj / e - hb[d] / (e * l) - c * ps[d];
        }
    }
}

// The rods' flow velocities v = [u]_l / l, w = p x (12 / l^3)(I - pp)[s u]_l (one thread per
// rod; slender.rs's flow_velocities; 6 per rod: v, w) and their velocities (triples): swimming
// at swim, the flow's, and with has_ft the local drag (trans, rot) of the contact force and
// torque (LocalDrag::local) (SlenderBody::solve_and_move).
extern "C" __global__ void slender_velocities(const double* p, const double* u, const double* s,
                                              const double* w, const double* ft, double* flow,
                                              double* vel, double* omega, int n, int m,
                                              double l, double swim, double trans, double rot,
                                              int has_ft) {
    int r = blockIdx.x * blockDim.x + threadIdx.x;
    if (r >= n) return;
    const double* ur = u + 3LL * r * m;
    double pn[3] = {p[3 * r], p[3 * r + 1], p[3 * r + 2]};
    double a[3], b[3];
    rod_moments(ur, s, w, m, a, b);
    double c = p4_dot(pn, b);
    double pd[3];
    for (int d = 0; d < 3; ++d) pd[d] = 12.0 / (l * l * l) * (b[d] - c * pn[d]);
    double dv[3] = {a[0] / l, a[1] / l, a[2] / l};
    double dw[3] = {pn[1] * pd[2] - pn[2] * pd[1], pn[2] * pd[0] - pn[0] * pd[2],
                    pn[0] * pd[1] - pn[1] * pd[0]};
    for (int d = 0; d < 3; ++d) {
        flow[6 * r + d] = dv[d];
        flow[6 * r + 3 + d] = dw[d];
    }
    // LocalDrag::local: v = trans (I + pp) f, w = rot (I - pp) t; zero without forces.
    double lv[3] = {0.0, 0.0, 0.0}, lw[3] = {0.0, 0.0, 0.0};
    if (has_ft) {
        const double* f = ft + 6 * r;
        const double* t = f + 3;
        double pf = p4_dot(pn, f), pt = p4_dot(pn, t);
        for (int d = 0; d < 3; ++d) {
            lv[d] = trans * (f[d] + pf * pn[d]);
            lw[d] = rot * (t[d] - pt * pn[d]);
        }
    }
    for (int d = 0; d < 3; ++d) {
        vel[3 * r + d] = swim * pn[d] + dv[d] + lv[d];
        omega[3 * r + d] = dw[d] + lw[d];
    }
}

// The prediction the contact solver plans with: swimming at swim plus the last flow velocities
// (6 per rod: v, w) (SlenderBody::predict).
extern "C" __global__ void slender_predict(const double* p, const double* flow, double* vel,
                                           double* omega, int n, double swim) {
    int r = blockIdx.x * blockDim.x + threadIdx.x;
    if (r >= n) return;
    for (int d = 0; d < 3; ++d) {
        vel[3 * r + d] = swim * p[3 * r + d] + flow[6 * r + d];
        omega[3 * r + d] = flow[6 * r + 3 + d];
    }
}

// Per chunk c (one block each): the sum of a[i] b[i] over its entries in order from -0.0
// (det_sum's partial), the products staged in shared memory by the block's threads and folded
// by its first.
#define KRYLOV_THREADS 256
extern "C" __global__ void krylov_dot_chunks(const double* a, const double* b, double* partial,
                                             int n, int chunk) {
    __shared__ double sh[KRYLOV_THREADS];
    int c = blockIdx.x, t = threadIdx.x;
    if ((long long)c * chunk >= n) return; // the whole block
    int hi = (c + 1) * chunk < n ? (c + 1) * chunk : n;
    double acc = -0.0;
    for (int k0 = c * chunk; k0 < hi; k0 += KRYLOV_THREADS) {
        int k = k0 + t;
        if (k < hi) sh[t] = a[k] * b[k];
        __syncthreads();
        if (t == 0) {
            int len = hi - k0 < KRYLOV_THREADS ? hi - k0 : KRYLOV_THREADS;
            for (int v = 0; v < len; ++v) acc += sh[v];
        }
        __syncthreads();
    }
    if (t == 0) partial[c] = acc;
}

// One thread: the chunks' partials summed in order from -0.0 into out[slot], or its square root
// with root (a norm).
extern "C" __global__ void krylov_fold(const double* partial, double* out, int nchunks,
                                       int slot, int root) {
    if (blockIdx.x * blockDim.x + threadIdx.x != 0) return;
    double acc = -0.0;
    for (int c = 0; c < nchunks; ++c) acc += partial[c];
    out[slot] = root ? sqrt(acc) : acc;
}

// w -= h[slot] v (a step of modified Gram-Schmidt).
extern "C" __global__ void krylov_axpy(double* w, const double* v, const double* h, int slot,
                                       int n) {
    int i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= n) return;
    w[i] -= h[slot] * v[i];
}

// dst = src / d.
extern "C" __global__ void krylov_div(const double* src, double* dst, double d, int n) {
    int i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= n) return;
    dst[i] = src[i] / d;
}

// w = b - w (the residual from the product A x in w).
extern "C" __global__ void krylov_residual(const double* b, double* w, int n) {
    int i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= n) return;
    w[i] = b[i] - w[i];
}

// x += y[j] v: one term of the update x += sum_j y_j v_j, launched in basis order (each entry
// then takes the terms in the CPU's order).
extern "C" __global__ void krylov_update(double* x, const double* v, const double* y, int j,
                                         int n) {
    int i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= n) return;
    x[i] += y[j] * v[i];
}
