// CUDA kernels of the mean-field step on the GPU (meanfield/src/gpu), compiled at run time by
// NVRTC. Each kernel is the device twin of a CPU loop in solver.rs and closure.rs, with the
// same formulas in the same order where it matters; the parity tests compare a GPU step with
// the CPU step to 1e-12. Layouts as on the CPU: a grid field is n^3 doubles, index
// (i2 n + i1) n + i0 with i0 fastest; a half spectrum is n n h complex values, h = n/2 + 1,
// index (i2 n + i1) h + i0. Symmetric tensors store xx, xy, xz, yy, yz, zz.

#define REDUCE_THREADS 256

__device__ __constant__ int SYM_I[6] = {0, 0, 0, 1, 1, 2};
__device__ __constant__ int SYM_J[6] = {0, 1, 2, 1, 2, 2};

// The row and column of symmetric component cc (SYM_I, SYM_J), as arithmetic: with cc a
// compile-time value (an unrolled loop) the indices are constants, no memory is read.
__device__ int sym_i(int cc) { return cc < 3 ? 0 : (cc < 5 ? 1 : 2); }
__device__ int sym_j(int cc) { return cc < 3 ? cc : (cc < 5 ? cc - 2 : 2); }

__device__ int sym_index(int i, int j) {
    int a = i < j ? i : j;
    int b = i < j ? j : i;
    if (a == 0) return b;          // 00 -> 0, 01 -> 1, 02 -> 2
    if (a == 1) return b + 2;      // 11 -> 3, 12 -> 4
    return 5;                      // 22
}

__device__ double2 times_i(double2 z, double k) {
    // i k z
    return make_double2(-k * z.y, k * z.x);
}

// Component m = i * 3 + k of the velocity gradient d_k u_i at point p: eight fields are stored
// (g[m N + p] for m < 8), and d_z u_z = -(d_x u_x + d_y u_y) (div u = 0).
__device__ double grad_at(const double* g, long long N, long long p, int m) {
    return m == 8 ? -(g[p] + g[4 * N + p]) : g[m * N + p];
}

// E_c = (g_ij + g_ji) / 2 at point p from the velocity gradient (grad_at).
__device__ void strain_at(const double* g, long long N, long long p, double e[6]) {
#pragma unroll
    for (int c = 0; c < 6; c++) {
        int i = sym_i(c), j = sym_j(c);
        e[c] = 0.5 * (grad_at(g, N, p, i * 3 + j) + grad_at(g, N, p, j * 3 + i));
    }
}

__device__ void block_sum(double* shared, double v, double* out) {
    int t = threadIdx.x;
    shared[t] = v;
    __syncthreads();
    for (int w = REDUCE_THREADS / 2; w > 0; w /= 2) {
        if (t < w) shared[t] += shared[t + w];
        __syncthreads();
    }
    if (t == 0) *out = shared[0];
    __syncthreads();
}

__device__ void block_max(double* shared, double v, double* out) {
    int t = threadIdx.x;
    shared[t] = v;
    __syncthreads();
    for (int w = REDUCE_THREADS / 2; w > 0; w /= 2) {
        if (t < w) shared[t] = fmax(shared[t], shared[t + w]);
        __syncthreads();
    }
    if (t == 0) *out = shared[0];
    __syncthreads();
}

// ---------------------------------------------------------------------------------------------
// Spectral loops.

// After a forward transform: scale by 1/n^3, and zero the modes the 2/3 rule drops; per block
// the count of non-finite values after (nonfinite_partials of the result, fused in).
extern "C" __global__ void scale_dealias(double2* c, long long count, int n, double scale,
                                         const int* keep, int dealias, double* partial) {
    __shared__ double shared[REDUCE_THREADS];
    long long t = blockIdx.x * (long long)blockDim.x + threadIdx.x;
    double bad = 0.0;
    if (t < count) {
        int h = n / 2 + 1;
        long long s = t % ((long long)n * n * h);
        int a = (int)(s % h);
        long long row = s / h;
        int b = (int)(row % n), d = (int)(row / n);
        bool kept = !dealias || (3 * a <= n && keep[b] != 0 && keep[d] != 0);
        double2 v = c[t];
        double2 r = kept ? make_double2(v.x * scale, v.y * scale) : make_double2(0.0, 0.0);
        c[t] = r;
        bad = (isfinite(r.x) ? 0.0 : 1.0) + (isfinite(r.y) ? 0.0 : 1.0);
    }
    block_sum(shared, bad, &partial[blockIdx.x]);
}

// The strain spectra (i/2)(k_j u_i + k_i u_j) of velocity spectra u (three components): the
// first five (xx, xy, xz, yy, yz); E is trace-free (div u = 0), so contract takes
// E_zz = -(E_xx + E_yy) and the fixed point transforms five fields, not six.
extern "C" __global__ void strain_spectra(const double2* u, double2* out, int n, const double* k1) {
    int h = n / 2 + 1;
    long long S = (long long)n * n * h;
    long long s = blockIdx.x * (long long)blockDim.x + threadIdx.x;
    if (s >= S) return;
    int a = (int)(s % h);
    long long row = s / h;
    double k[3] = {k1[a], k1[row % n], k1[row / n]};
#pragma unroll
    for (int c = 0; c < 5; c++) {
        int i = sym_i(c), j = sym_j(c);
        double2 ui = u[i * S + s], uj = u[j * S + s];
        // 0.5 i (u_i k_j + u_j k_i)
        double2 w = make_double2(ui.x * k[j] + uj.x * k[i], ui.y * k[j] + uj.y * k[i]);
        out[c * S + s] = make_double2(-0.5 * w.y, 0.5 * w.x);
    }
}

// Derivative spectra: out[(m * 3 + dir) S + s] = i k_dir c[(first + m) S + s] for `comps`
// inputs from component `first` on.
extern "C" __global__ void derivative_spectra(const double2* c, int first, double2* out, int comps,
                                              int n, const double* k1) {
    int h = n / 2 + 1;
    long long S = (long long)n * n * h;
    long long s = blockIdx.x * (long long)blockDim.x + threadIdx.x;
    if (s >= S) return;
    int a = (int)(s % h);
    long long row = s / h;
    double k[3] = {k1[a], k1[row % n], k1[row / n]};
    for (int m = 0; m < comps; m++) {
        double2 v = c[(first + m) * S + s];
        for (int dir = 0; dir < 3; dir++) out[(m * 3 + dir) * S + s] = times_i(v, k[dir]);
    }
}

// Half-spectrum index s of an n^3 grid: its wavenumbers k, whether the 2/3 rule keeps it
// (scale_dealias's test), and |k|^2 (k2 summed as in stokes_into) returned.
__device__ double mode_wavenumbers(long long s, int n, const double* k1, const double* k2,
                                   const int* keep, double k[3], bool* kept) {
    int h = n / 2 + 1;
    int a = (int)(s % h);
    long long row = s / h;
    int b = (int)(row % n), d = (int)(row / n);
    *kept = 3 * a <= n && keep[b] != 0 && keep[d] != 0;
    k[0] = k1[a];
    k[1] = k1[b];
    k[2] = k1[d];
    return k2[a] + k2[b] + k2[d];
}

// One mode of the zero-mean Stokes velocity u = (I - kk/k^2)/k^2 . (i k . sigma) of a
// symmetric stress sig (grid.rs stokes_into, the same operations in the same order); kk > 0.
__device__ void stokes_mode(const double2 sig[6], const double k[3], double kk, double2 u[3]) {
    double2 f[3];
#pragma unroll
    for (int i = 0; i < 3; i++) {
        double2 sum = make_double2(0.0, 0.0);
#pragma unroll
        for (int j = 0; j < 3; j++) {
            double2 sij = sig[sym_index(i, j)];
            sum.x += k[j] * sij.x;
            sum.y += k[j] * sij.y;
        }
        f[i] = make_double2(-sum.y, sum.x); // i * sum
    }
    double2 kf = make_double2(k[0] * f[0].x + k[1] * f[1].x + k[2] * f[2].x,
                              k[0] * f[0].y + k[1] * f[1].y + k[2] * f[2].y);
    double k1sq = fmax(k[0] * k[0] + k[1] * k[1] + k[2] * k[2], 1e-300);
#pragma unroll
    for (int i = 0; i < 3; i++) {
        double c = k[i] / k1sq;
        u[i] = make_double2((f[i].x - kf.x * c) / kk, (f[i].y - kf.y * c) / kk);
    }
}

// Zero-mean Stokes velocity of a trace-free stress from the spectra of its first five
// components (contract), each scaled by `scale` and dealiased by the 2/3 rule as it is read
// (scale_dealias fused in), sigma_zz = -(sigma_xx + sigma_yy).
extern "C" __global__ void stokes(const double2* sigma, double2* u, int n, const double* k1,
                                  const double* k2, double scale, const int* keep) {
    long long S = (long long)n * n * (n / 2 + 1);
    long long s = blockIdx.x * (long long)blockDim.x + threadIdx.x;
    if (s >= S) return;
    double k[3];
    bool kept;
    double kk = mode_wavenumbers(s, n, k1, k2, keep, k, &kept);
    if (kk == 0.0 || !kept) {
        // A dropped mode's stress is zero, and so is its velocity (the unfused kernels gave
        // +-0 there; the velocity is only ever added to or transformed).
        for (int i = 0; i < 3; i++) u[i * S + s] = make_double2(0.0, 0.0);
        return;
    }
    double2 sig[6];
#pragma unroll
    for (int c = 0; c < 5; c++) {
        double2 v = sigma[c * S + s];
        sig[c] = make_double2(v.x * scale, v.y * scale);
    }
    sig[5] = make_double2(-(sig[0].x + sig[3].x), -(sig[0].y + sig[3].y));
    double2 out[3];
    stokes_mode(sig, k, kk, out);
    for (int i = 0; i < 3; i++) u[i * S + s] = out[i];
}

// The fixed point's first iterate (stepper.rs warm_start): u = u_hat + the Stokes velocity of
// -(Q - Q_prev) over the modes the 2/3 rule keeps.
extern "C" __global__ void warm_start(const double2* q, const double2* q_prev, const double2* u_hat,
                                      double2* u, int n, const double* k1, const double* k2,
                                      const int* keep) {
    long long S = (long long)n * n * (n / 2 + 1);
    long long s = blockIdx.x * (long long)blockDim.x + threadIdx.x;
    if (s >= S) return;
    double k[3];
    bool kept;
    double kk = mode_wavenumbers(s, n, k1, k2, keep, k, &kept);
    double2 out[3] = {make_double2(0.0, 0.0), make_double2(0.0, 0.0), make_double2(0.0, 0.0)};
    if (kk != 0.0) {
        double2 sig[6];
#pragma unroll
        for (int c = 0; c < 6; c++) {
            double2 v = q[c * S + s], w = q_prev[c * S + s];
            sig[c] = kept ? make_double2(-(v.x - w.x), -(v.y - w.y)) : make_double2(0.0, 0.0);
        }
        stokes_mode(sig, k, kk, out);
    }
    for (int i = 0; i < 3; i++) {
        double2 g = u_hat[i * S + s];
        u[i * S + s] = make_double2(g.x + out[i].x, g.y + out[i].y);
    }
}

// Variable-step IMEX update (SBDF1 when `two` is 0), six components:
// out = (-a1 q + dt b0 N [- a2 q_prev + dt b1 N_prev]) / (a0 + dt D |k|^2); per block the
// count of non-finite values written (nonfinite_partials of the result, fused in).
extern "C" __global__ void imex_update(const double2* q, const double2* nl, const double2* q_prev,
                                       const double2* nl_prev, double2* out, int n,
                                       const double* k2, double a0, double a1, double a2,
                                       double b0, double b1, double dt, double diffusion,
                                       int two, double* partial) {
    __shared__ double shared[REDUCE_THREADS];
    int h = n / 2 + 1;
    long long S = (long long)n * n * h;
    long long s = blockIdx.x * (long long)blockDim.x + threadIdx.x;
    double bad = 0.0;
    if (s < S) {
        int a = (int)(s % h);
        long long row = s / h;
        double kk = k2[a] + k2[row % n] + k2[row / n];
        double den = a0 + dt * diffusion * kk;
        for (int c = 0; c < 6; c++) {
            long long i = c * S + s;
            double2 r = make_double2(-a1 * q[i].x + dt * b0 * nl[i].x,
                                     -a1 * q[i].y + dt * b0 * nl[i].y);
            if (two) {
                r.x += -a2 * q_prev[i].x + dt * b1 * nl_prev[i].x;
                r.y += -a2 * q_prev[i].y + dt * b1 * nl_prev[i].y;
            }
            double2 o = make_double2(r.x / den, r.y / den);
            out[i] = o;
            bad += (isfinite(o.x) ? 0.0 : 1.0) + (isfinite(o.y) ? 0.0 : 1.0);
        }
    }
    block_sum(shared, bad, &partial[blockIdx.x]);
}

// ---------------------------------------------------------------------------------------------
// Deterministic block reductions: each block sums its fixed range in a fixed tree order and
// writes one partial per block; the host adds the partials in block order.

__device__ double spectral_weight(long long s, int n) {
    int h = n / 2 + 1;
    int a = (int)(s % h);
    return (a == 0 || a == n / 2) ? 1.0 : 2.0;
}

// Partials of sum w |a - b|^2 and sum w |a|^2 over three spectra (the fixed point's change).
extern "C" __global__ void change_partials(const double2* a, const double2* b, int n,
                                           double* partial) {
    __shared__ double shared[REDUCE_THREADS];
    int h = n / 2 + 1;
    long long S = (long long)n * n * h;
    long long s = blockIdx.x * (long long)blockDim.x + threadIdx.x;
    double num = 0.0, den = 0.0;
    if (s < S) {
        double w = spectral_weight(s, n);
        for (int c = 0; c < 3; c++) {
            double2 x = a[c * S + s], y = b[c * S + s];
            double dx = x.x - y.x, dy = x.y - y.y;
            num += w * (dx * dx + dy * dy);
            den += w * (x.x * x.x + x.y * x.y);
        }
    }
    block_sum(shared, num, &partial[2 * blockIdx.x]);
    block_sum(shared, den, &partial[2 * blockIdx.x + 1]);
}

// Partials of sum w |u|^2 over three spectra (||u||_2^2 by Parseval).
extern "C" __global__ void norm_partials(const double2* u, int n, double* partial) {
    __shared__ double shared[REDUCE_THREADS];
    int h = n / 2 + 1;
    long long S = (long long)n * n * h;
    long long s = blockIdx.x * (long long)blockDim.x + threadIdx.x;
    double v = 0.0;
    if (s < S) {
        double w = spectral_weight(s, n);
        for (int c = 0; c < 3; c++) {
            double2 x = u[c * S + s];
            v += w * (x.x * x.x + x.y * x.y);
        }
    }
    block_sum(shared, v, &partial[blockIdx.x]);
}

// Partials of the step report: max(|u_x| + |u_y| + |u_z|), <E:E>, <E:Q>, <E:S:E> (weighted
// sums over the six components), E from the velocity gradient g as strain_at. The velocity's
// three fields start at ug + ug_at.
extern "C" __global__ void report_partials(const double* ug, long long ug_at, const double* g,
                                           const double* q, const double* se, long long N,
                                           double* partial) {
    __shared__ double shared[REDUCE_THREADS];
    long long p = blockIdx.x * (long long)blockDim.x + threadIdx.x;
    ug += ug_at;
    double umax = 0.0, ee = 0.0, eq = 0.0, ese = 0.0;
    if (p < N) {
        umax = fabs(ug[p]) + fabs(ug[N + p]) + fabs(ug[2 * N + p]);
        double e[6];
        strain_at(g, N, p, e);
#pragma unroll
        for (int c = 0; c < 6; c++) {
            double w = (sym_i(c) == sym_j(c)) ? 1.0 : 2.0;
            double ec = e[c];
            ee += w * ec * ec;
            eq += w * ec * q[c * N + p];
            ese += w * ec * se[c * N + p];
        }
    }
    block_max(shared, umax, &partial[4 * blockIdx.x]);
    block_sum(shared, ee, &partial[4 * blockIdx.x + 1]);
    block_sum(shared, eq, &partial[4 * blockIdx.x + 2]);
    block_sum(shared, ese, &partial[4 * blockIdx.x + 3]);
}


// ---------------------------------------------------------------------------------------------
// Pointwise grid loops.

// S:E at one point from its stored lab-frame tensor m (21 values, rows of the upper
// triangle) and E's six components.
__device__ void contract_point(const double* m, const double e[6], double t[6]) {
    double w[6] = {e[0], 2.0 * e[1], 2.0 * e[2], e[3], 2.0 * e[4], e[5]};
    t[0] = m[0] * w[0] + m[1] * w[1] + m[2] * w[2] + m[3] * w[3] + m[4] * w[4] + m[5] * w[5];
    t[1] = m[1] * w[0] + m[6] * w[1] + m[7] * w[2] + m[8] * w[3] + m[9] * w[4] + m[10] * w[5];
    t[2] = m[2] * w[0] + m[7] * w[1] + m[11] * w[2] + m[12] * w[3] + m[13] * w[4] + m[14] * w[5];
    t[3] = m[3] * w[0] + m[8] * w[1] + m[12] * w[2] + m[15] * w[3] + m[16] * w[4] + m[17] * w[5];
    t[4] = m[4] * w[0] + m[9] * w[1] + m[13] * w[2] + m[16] * w[3] + m[18] * w[4] + m[19] * w[5];
    t[5] = m[5] * w[0] + m[10] * w[1] + m[14] * w[2] + m[17] * w[3] + m[19] * w[4] + m[20] * w[5];
}

// The active stress -q + zeta S:E from the stored lab-frame tensors and the grid E (its first
// five components; E_zz = -(E_xx + E_yy)), its deviatoric part's first five components
// written over e in place (a thread reads its point's E values before it writes any): the
// isotropic part drives no flow (stokes projects it out), so the fixed point transforms five
// fields, and stokes takes sigma_zz = -(sigma_xx + sigma_yy).
extern "C" __global__ void contract(const double* s21, double* e, const double* q, double zeta,
                                    long long N) {
    long long p = blockIdx.x * (long long)blockDim.x + threadIdx.x;
    if (p >= N) return;
    double ep[6] = {e[p], e[N + p], e[2 * N + p], e[3 * N + p], e[4 * N + p], 0.0};
    ep[5] = -(ep[0] + ep[3]);
    double t[6], sig[6];
    contract_point(s21 + 21 * p, ep, t);
    // With zeta = 0 the stress is -Q alone (as on the CPU, which skips the contraction then).
#pragma unroll
    for (int c = 0; c < 6; c++) sig[c] = zeta != 0.0 ? -q[c * N + p] + zeta * t[c] : -q[c * N + p];
    double third = (sig[0] + sig[3] + sig[5]) / 3.0;
    sig[0] -= third;
    sig[3] -= third;
#pragma unroll
    for (int c = 0; c < 5; c++) e[c * N + p] = sig[c];
}

// S:E over the grid, E from the velocity gradient g as strain_at, into se.
extern "C" __global__ void contract_gradient(const double* s21, const double* g, double* se,
                                             long long N) {
    long long p = blockIdx.x * (long long)blockDim.x + threadIdx.x;
    if (p >= N) return;
    double e[6], t[6];
    strain_at(g, N, p, e);
    contract_point(s21 + 21 * p, e, t);
    for (int c = 0; c < 6; c++) se[c * N + p] = t[c];
}

// The explicit terms -u.grad Q + (grad u) Q + Q (grad u)^T - 2 S:E at every point, six
// components, written over S:E in place (component c of a point is read just before it is
// written): ug + ug_at the velocity (3 N; it may share a buffer with dq),
// g[(i * 3 + k) N] = d_k u_i, dq[(c * 3 + k) N] = d_k Q_c.
extern "C" __global__ void explicit_terms(const double* ug, long long ug_at, const double* g,
                                          const double* q, const double* dq, double* se,
                                          long long N) {
    long long p = blockIdx.x * (long long)blockDim.x + threadIdx.x;
    if (p >= N) return;
    ug += ug_at;
#pragma unroll
    for (int c = 0; c < 6; c++) {
        int i = sym_i(c), j = sym_j(c);
        double adv = ug[p] * dq[(c * 3 + 0) * N + p] + ug[N + p] * dq[(c * 3 + 1) * N + p] +
                     ug[2 * N + p] * dq[(c * 3 + 2) * N + p];
        double stretch = 0.0;
#pragma unroll
        for (int k = 0; k < 3; k++) {
            stretch += grad_at(g, N, p, i * 3 + k) * q[sym_index(k, j) * N + p] +
                       q[sym_index(i, k) * N + p] * grad_at(g, N, p, j * 3 + k);
        }
        se[c * N + p] = -adv + stretch - 2.0 * se[c * N + p];
    }
}

// ---------------------------------------------------------------------------------------------
// The closure field: eigen-decomposition of Q / tr Q (closed form as eigen.rs, Jacobi sweeps
// for nearly isotropic matrices), the Chebyshev tables, the lab-frame tensor (as lab_fourth).

__device__ void cross3(const double* a, const double* b, double* out) {
    out[0] = a[1] * b[2] - a[2] * b[1];
    out[1] = a[2] * b[0] - a[0] * b[2];
    out[2] = a[0] * b[1] - a[1] * b[0];
}

__device__ double dot3(const double* a, const double* b) {
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

// No small array of the closure's per-point code is indexed with a run-time index: such an
// index puts the array in local memory (a 232-byte stack frame before, read and written at
// every access); with compile-time indices (templates, unrolled loops, selects) every value
// stays in a register. The floating-point operations and their order are unchanged.

// One Jacobi rotation of the pair (p, q) (p, q template arguments: constant indices).
template <int p, int q>
__device__ void jacobi_rotate(double m[3][3], double r[3][3]) {
    if (m[p][q] == 0.0) return;
    double theta = (m[q][q] - m[p][p]) / (2.0 * m[p][q]);
    double t = (theta >= 0.0 ? 1.0 : -1.0) / (fabs(theta) + sqrt(theta * theta + 1.0));
    if (theta == 0.0) t = 1.0;
    double c = 1.0 / sqrt(t * t + 1.0);
    double s = t * c;
#pragma unroll
    for (int k = 0; k < 3; k++) {
        double mkp = m[k][p], mkq = m[k][q];
        m[k][p] = c * mkp - s * mkq;
        m[k][q] = s * mkp + c * mkq;
    }
#pragma unroll
    for (int k = 0; k < 3; k++) {
        double mpk = m[p][k], mqk = m[q][k];
        m[p][k] = c * mpk - s * mqk;
        m[q][k] = s * mpk + c * mqk;
    }
#pragma unroll
    for (int k = 0; k < 3; k++) {
        double rkp = r[k][p], rkq = r[k][q];
        r[k][p] = c * rkp - s * rkq;
        r[k][q] = s * rkp + c * rkq;
    }
}

// Cyclic Jacobi rotations (the slow twin, eigen.rs sym3_eigen): w eigenvalues, r columns.
__device__ void jacobi3(const double am[3][3], double w[3], double r[3][3]) {
    double m[3][3];
#pragma unroll
    for (int i = 0; i < 3; i++)
#pragma unroll
        for (int j = 0; j < 3; j++) {
            m[i][j] = am[i][j];
            r[i][j] = i == j ? 1.0 : 0.0;
        }
    for (int sweep = 0; sweep < 50; sweep++) {
        double off = fabs(m[0][1]) + fabs(m[0][2]) + fabs(m[1][2]);
        double scale = fabs(m[0][0]) + fabs(m[1][1]) + fabs(m[2][2]);
        if (off <= 1e-300 || off <= 2.220446049250313e-16 * 1e-3 * scale) break;
        jacobi_rotate<0, 1>(m, r);
        jacobi_rotate<0, 2>(m, r);
        jacobi_rotate<1, 2>(m, r);
    }
    w[0] = m[0][0];
    w[1] = m[1][1];
    w[2] = m[2][2];
}

// Positions a < b of the sort: the value at b moves first if strictly larger (ties keep their
// order), its eigenvector column with it.
template <int a, int b>
__device__ void order_pair(double w[3], double r[3][3]) {
    if (w[b] > w[a]) {
        double t = w[a];
        w[a] = w[b];
        w[b] = t;
#pragma unroll
        for (int i = 0; i < 3; i++) {
            double u = r[i][a];
            r[i][a] = r[i][b];
            r[i][b] = u;
        }
    }
}

// Eigenvalues descending, eigenvector columns permuted with them (stable for ties): the
// bubble sort's comparisons (0, 1), (1, 2), (0, 1) as a fixed network on the values, the same
// permutation as bubble-sorting an index array.
__device__ void sort_desc(double w[3], double r[3][3]) {
    order_pair<0, 1>(w, r);
    order_pair<1, 2>(w, r);
    order_pair<0, 1>(w, r);
}

// The closed form (eigen.rs): false where it does not apply (the caller then uses jacobi3),
// else w and r unsorted.
__device__ bool eigen_closed(const double a[3][3], double w[3], double r[3][3]) {
    double c = (a[0][0] + a[1][1] + a[2][2]) / 3.0;
    double b0 = a[0][0] - c, b1 = a[1][1] - c, b2 = a[2][2] - c;
    double off2 = a[0][1] * a[0][1] + a[0][2] * a[0][2] + a[1][2] * a[1][2];
    double p2 = (b0 * b0 + b1 * b1 + b2 * b2 + 2.0 * off2) / 6.0;
    double scale = fabs(a[0][0]) + fabs(a[1][1]) + fabs(a[2][2]) + sqrt(off2);
    if (isnan(p2) || p2 <= 0.0 || sqrt(6.0 * p2) <= 1e-9 * scale) return false;
    double p = sqrt(p2);
    double det = b0 * (b1 * b2 - a[1][2] * a[1][2]) - a[0][1] * (a[0][1] * b2 - a[1][2] * a[0][2]) +
                 a[0][2] * (a[0][1] * a[1][2] - b1 * a[0][2]);
    double rr = fmin(fmax(det / (2.0 * p * p2), -1.0), 1.0);
    double phi = acos(rr) / 3.0;
    double l1 = c + 2.0 * p * cos(phi);
    double l3 = c + 2.0 * p * cos(phi + 2.0943951023931953);
    double l2 = 3.0 * c - l1 - l3;
    bool largest = l1 - l2 >= l2 - l3;
    double iso = largest ? l1 : l3;
    double rows[3][3] = {{a[0][0] - iso, a[0][1], a[0][2]},
                         {a[0][1], a[1][1] - iso, a[1][2]},
                         {a[0][2], a[1][2], a[2][2] - iso}};
    double cr[3][3];
    cross3(rows[0], rows[1], cr[0]);
    cross3(rows[0], rows[2], cr[1]);
    cross3(rows[1], rows[2], cr[2]);
    double nr[3] = {dot3(cr[0], cr[0]), dot3(cr[1], cr[1]), dot3(cr[2], cr[2])};
    // The longest cross product, selected by value.
    int k = (nr[0] >= nr[1] && nr[0] >= nr[2]) ? 0 : (nr[1] >= nr[2] ? 1 : 2);
    double nk = k == 0 ? nr[0] : (k == 1 ? nr[1] : nr[2]);
    if (isnan(nk) || nk <= 0.0) return false;
    double v[3], inv = 1.0 / sqrt(nk);
#pragma unroll
    for (int d = 0; d < 3; d++) v[d] = (k == 0 ? cr[0][d] : (k == 1 ? cr[1][d] : cr[2][d])) * inv;
    double axis[3] = {0.0, 0.0, 0.0};
    if (fabs(v[0]) <= fabs(v[1]) && fabs(v[0]) <= fabs(v[2])) axis[0] = 1.0;
    else if (fabs(v[1]) <= fabs(v[2])) axis[1] = 1.0;
    else axis[2] = 1.0;
    double u[3], wv[3];
    cross3(v, axis, u);
    double un = 1.0 / sqrt(dot3(u, u));
    for (int d = 0; d < 3; d++) u[d] *= un;
    cross3(v, u, wv);
    double au[3], aw[3], av[3];
#pragma unroll
    for (int i = 0; i < 3; i++) {
        au[i] = dot3(a[i], u);
        aw[i] = dot3(a[i], wv);
        av[i] = dot3(a[i], v);
    }
    double muu = dot3(u, au), mww = dot3(wv, aw), muw = dot3(u, aw);
    double e1 = muu, e2 = mww, t1[3], t2[3];
    for (int d = 0; d < 3; d++) {
        t1[d] = u[d];
        t2[d] = wv[d];
    }
    if (muw != 0.0) {
        double theta = (mww - muu) / (2.0 * muw);
        double t = (theta >= 0.0 ? 1.0 : -1.0) / (fabs(theta) + sqrt(theta * theta + 1.0));
        double cs = 1.0 / sqrt(t * t + 1.0);
        double sn = t * cs;
        e1 = muu - t * muw;
        e2 = mww + t * muw;
        for (int d = 0; d < 3; d++) {
            t1[d] = cs * u[d] - sn * wv[d];
            t2[d] = sn * u[d] + cs * wv[d];
        }
    }
    double lv = dot3(v, av);
    // The pair's larger eigenvalue first; copies (pointers to the columns were run-time indices).
    bool swap = e1 < e2;
    double hi = swap ? e2 : e1, lo = swap ? e1 : e2;
    double vh[3], vl[3];
#pragma unroll
    for (int d = 0; d < 3; d++) {
        vh[d] = swap ? t2[d] : t1[d];
        vl[d] = swap ? t1[d] : t2[d];
    }
    if (largest) {
        w[0] = lv; w[1] = hi; w[2] = lo;
#pragma unroll
        for (int i = 0; i < 3; i++) {
            r[i][0] = v[i]; r[i][1] = vh[i]; r[i][2] = vl[i];
        }
    } else {
        w[0] = hi; w[1] = lo; w[2] = lv;
#pragma unroll
        for (int i = 0; i < 3; i++) {
            r[i][0] = vh[i]; r[i][1] = vl[i]; r[i][2] = v[i];
        }
    }
    return true;
}

// Eigenvalues descending with their eigenvector columns: the closed form, else Jacobi sweeps.
__device__ void eigen_sorted(const double a[3][3], double w[3], double r[3][3]) {
    if (!eigen_closed(a, w, r)) jacobi3(a, w, r);
    sort_desc(w, r);
}

// T_k(s) for k = 0, 1, 2, ... in turn: (a, b) start at (1, s) and hold (T_{k-1}, T_k) after.
__device__ double chebyshev_next(int k, double s, double* a, double* b) {
    if (k == 0) return 1.0;
    if (k > 1) {
        double t = 2.0 * s * *b - *a;
        *a = *b;
        *b = t;
    }
    return *b;
}

// The T tables' double Chebyshev sums at (sx, sy) into f[0..T): T a compile-time count, so
// that the per-table sums stay in registers (with a run-time count they went to local memory,
// read and written at every coefficient). The order of the sums is the CPU's (closure.rs).
template <int T>
__device__ void chebyshev_tables(const double* coef, int n1, double sx, double sy, double* f) {
    double acc[T];
    for (int t3 = 0; t3 < T; t3++) acc[t3] = 0.0;
    double txa = 1.0, txb = sx;
    for (int i = 0; i < n1; i++) {
        double tx = chebyshev_next(i, sx, &txa, &txb);
        double rowv[T];
        for (int t3 = 0; t3 < T; t3++) rowv[t3] = 0.0;
        double tya = 1.0, tyb = sy;
        for (int j = 0; j < n1; j++) {
            double ty = chebyshev_next(j, sy, &tya, &tyb);
            for (int t3 = 0; t3 < T; t3++) rowv[t3] += ty * coef[(t3 * n1 + i) * n1 + j];
        }
        for (int t3 = 0; t3 < T; t3++) acc[t3] += tx * rowv[t3];
    }
    for (int t3 = 0; t3 < T; t3++) f[t3] = acc[t3];
}

// The default degree's tables (deg 20, closure.rs DEFAULT_DEGREE), staged in shared memory
// once per block: every thread of a warp reads the same coefficient at the same time, a
// shared-memory broadcast instead of a global load per coefficient. Layout [t][i][k], the pair
// (c[t][i][2k], c[t][i][2k + 1]) as one double2 (one 16-byte load for two coefficients), the
// last pair of a row padded with 0 (never read).
#define CHEB_N1 21
#define CHEB_PAIRS ((CHEB_N1 + 1) / 2)

__device__ void stage_tables(const double* coef, int tables, double2* tab) {
    for (int e = threadIdx.x; e < tables * CHEB_N1 * CHEB_PAIRS; e += blockDim.x) {
        int row = e / CHEB_PAIRS, j = 2 * (e % CHEB_PAIRS);
        const double* c = coef + row * CHEB_N1;
        tab[e] = make_double2(c[j], j + 1 < CHEB_N1 ? c[j + 1] : 0.0);
    }
}

// chebyshev_tables for n1 = CHEB_N1 from the staged tables, the same sums in the same order:
// T_j(sy) computed once per point into registers by the same recurrence (the generic loop
// recomputes the same values for every row), the j loop unrolled so that they stay there.
template <int T>
__device__ void chebyshev_tables_staged(const double2* tab, double sx, double sy, double* f) {
    double ty[CHEB_N1];
    double tya = 1.0, tyb = sy;
#pragma unroll
    for (int j = 0; j < CHEB_N1; j++) ty[j] = chebyshev_next(j, sy, &tya, &tyb);
    double acc[T];
#pragma unroll
    for (int t3 = 0; t3 < T; t3++) acc[t3] = 0.0;
    double txa = 1.0, txb = sx;
    for (int i = 0; i < CHEB_N1; i++) {
        double tx = chebyshev_next(i, sx, &txa, &txb);
        double rowv[T];
#pragma unroll
        for (int t3 = 0; t3 < T; t3++) rowv[t3] = 0.0;
#pragma unroll
        for (int k = 0; k < CHEB_PAIRS; k++)
#pragma unroll
            for (int t3 = 0; t3 < T; t3++) {
                double2 c = tab[(t3 * CHEB_N1 + i) * CHEB_PAIRS + k];
                rowv[t3] += ty[2 * k] * c.x;
                if (2 * k + 1 < CHEB_N1) rowv[t3] += ty[2 * k + 1] * c.y;
            }
#pragma unroll
        for (int t3 = 0; t3 < T; t3++) acc[t3] += tx * rowv[t3];
    }
#pragma unroll
    for (int t3 = 0; t3 < T; t3++) f[t3] = acc[t3];
}

// The lab-frame tensor's component indices, compile-time where cc is (SYM_I, SYM_J).

// One point of the closure field, first half: c = tr Q, w and r the eigenvalues and
// eigenvectors of Q / c, f the tables at its collapsed coordinates, lo/hi the extreme
// eigenvalues, ent the entropy density c ln c + c h(Q/c) (when asked). coef: four tables of
// (deg + 1)^2 Chebyshev coefficients, [f][i (x)][j (y)]: S_1111, S_2222, S_1122 and the
// entropy's regular part; tab the staged tables (read where staged, for deg = CHEB_N1 - 1).
__device__ void closure_moments(const double* q, long long N, long long p, const double* coef,
                                const double2* tab, bool staged, int deg, int with_entropy,
                                double* c_out, double w[3], double r[3][3], double f[4],
                                double* lo, double* hi, double* ent) {
    double a[3][3];
#pragma unroll
    for (int i = 0; i < 3; i++)
#pragma unroll
        for (int j = 0; j < 3; j++) a[i][j] = q[sym_index(i, j) * N + p];
    double c = a[0][0] + a[1][1] + a[2][2];
#pragma unroll
    for (int i = 0; i < 3; i++)
#pragma unroll
        for (int j = 0; j < 3; j++) a[i][j] /= c;
    *c_out = c;
    eigen_sorted(a, w, r);
    *lo = w[2];
    *hi = w[0];
    // Collapsed coordinates (closure.rs collapsed) and the tables.
    double x = fmin(fmax(w[0], 0.0), 1.0);
    double y = x < 1.0 ? fmin(fmax(w[1] / (1.0 - x), 0.0), 1.0) : 0.5;
    double sx = 2.0 * x - 1.0, sy = 2.0 * y - 1.0;
    int n1 = deg + 1;
    f[3] = 0.0;
    if (staged && with_entropy) {
        chebyshev_tables_staged<4>(tab, sx, sy, f);
    } else if (staged) {
        chebyshev_tables_staged<3>(tab, sx, sy, f);
    } else if (with_entropy) {
        chebyshev_tables<4>(coef, n1, sx, sy, f);
    } else {
        chebyshev_tables<3>(coef, n1, sx, sy, f);
    }
    if (with_entropy) {
        // h = table - (1/2) sum ln mu_i (closure.rs log_singularity).
        double sing = 0.5 * (log(fmax(w[0], 1e-300)) + log(fmax(w[1], 1e-300)) +
                             log(fmax(w[2], 1e-300)));
        *ent = c * log(fmax(c, 1e-300)) + c * (f[3] - sing);
    }
}

// Second half: s21 the lab-frame tensor (as lab_fourth) from closure_moments' c, w, r, f.
__device__ void lab_tensor(double c, const double w[3], const double r[3][3], const double f[4],
                           double* s21) {
    // The full S_iijj from the three tabulated ones and sum_j S_iijj = mu_i, scaled by c.
    double s11 = f[0], s22 = f[1], s12 = f[2];
    double s13 = w[0] - s11 - s12;
    double s23 = w[1] - s22 - s12;
    double s33 = w[2] - s13 - s23;
    double s[3][3] = {{s11 * c, s12 * c, s13 * c}, {s12 * c, s22 * c, s23 * c}, {s13 * c, s23 * c, s33 * c}};
    // Lab frame: S = sum_ab s_ab P^a P^b + sum_{a<b} s_ab Q^ab Q^ab.
    double P[3][6], Qm[3][6];
#pragma unroll
    for (int cc = 0; cc < 6; cc++) {
        int i = sym_i(cc), j = sym_j(cc);
#pragma unroll
        for (int aa = 0; aa < 3; aa++) P[aa][cc] = r[i][aa] * r[j][aa];
        Qm[0][cc] = r[i][0] * r[j][1] + r[i][1] * r[j][0];
        Qm[1][cc] = r[i][0] * r[j][2] + r[i][2] * r[j][0];
        Qm[2][cc] = r[i][1] * r[j][2] + r[i][2] * r[j][1];
    }
    double sp[3][6];
#pragma unroll
    for (int b = 0; b < 3; b++)
#pragma unroll
        for (int cc = 0; cc < 6; cc++)
            sp[b][cc] = s[0][b] * P[0][cc] + s[1][b] * P[1][cc] + s[2][b] * P[2][cc];
    double qs[3] = {s[0][1], s[0][2], s[1][2]};
    int k = 0;
#pragma unroll
    for (int cc = 0; cc < 6; cc++)
#pragma unroll
        for (int d = cc; d < 6; d++) {
            s21[k] = P[0][cc] * sp[0][d] + P[1][cc] * sp[1][d] + P[2][cc] * sp[2][d] +
                     qs[0] * Qm[0][cc] * Qm[0][d] + qs[1] * Qm[1][cc] * Qm[1][d] +
                     qs[2] * Qm[2][cc] * Qm[2][d];
            k++;
        }
}

// The closure field over the grid, with per-block partials: partial[3 b] = -(smallest
// eigenvalue), partial[3 b + 1] = largest eigenvalue, partial[3 b + 2] = sum of the entropy
// density (0 unless asked). Two blocks per multiprocessor asked for: at most 128 registers
// (the compiler's choice, 168, left one block of 8 warps; three blocks spill).
extern "C" __global__ void __launch_bounds__(REDUCE_THREADS, 2) closure_field(const double* q, double* s21, const double* coef, int deg,
                                         int with_entropy, long long N, double* partial) {
    __shared__ double shared[REDUCE_THREADS];
    // One buffer, two uses: the staged tables, then the block's tensors (point-major, as s21),
    // written out by consecutive threads (a thread writing its own 21 values, 168 bytes apart
    // from its neighbour's, made every store touch 32 sectors). 43 KB: with the reductions'
    // 2 KB, under the 48 KB of static shared memory.
    __shared__ union {
        double2 tab[4 * CHEB_N1 * CHEB_PAIRS];
        double out[21 * REDUCE_THREADS];
    } buf;
    // deg is the launch's: every thread of the block stages or none does. All threads reach
    // every barrier (the p < N tests are around the work only).
    bool staged = deg + 1 == CHEB_N1;
    if (staged) {
        stage_tables(coef, with_entropy ? 4 : 3, buf.tab);
        __syncthreads();
    }
    long long first = blockIdx.x * (long long)blockDim.x;
    long long p = first + threadIdx.x;
    double lo = 1e300, hi = -1e300, ent = 0.0, c = 0.0, w[3], r[3][3], f[4];
    if (p < N)
        closure_moments(q, N, p, coef, buf.tab, staged, deg, with_entropy, &c, w, r, f, &lo,
                        &hi, &ent);
    __syncthreads(); // every thread done with the tables before they are overwritten
    if (p < N) lab_tensor(c, w, r, f, buf.out + 21 * threadIdx.x);
    __syncthreads();
    long long count = 21 * (N - first < (long long)blockDim.x ? N - first : (long long)blockDim.x);
    for (long long e = threadIdx.x; e < count; e += blockDim.x) s21[21 * first + e] = buf.out[e];
    block_max(shared, -lo, &partial[3 * blockIdx.x]);
    block_max(shared, hi, &partial[3 * blockIdx.x + 1]);
    block_sum(shared, ent, &partial[3 * blockIdx.x + 2]);
}
