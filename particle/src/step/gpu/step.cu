// Joining the rooms into a step of the local-drag (`none`) level: the swimming velocities, the
// contact velocities added, the true overlaps after the move. Appended after contacts.cu (it
// uses quat_axis and pair_constraint).

// v = u p (p the axis of quaternion q), w = 0: LocalDrag::free_velocities.
extern "C" __global__ void swim_velocities(const double* q, double* v, double* w, int n,
                                           double u) {
    int r = blockIdx.x * blockDim.x + threadIdx.x;
    if (r >= n) return;
    double p[3];
    quat_axis(q + 4 * r, p);
    for (int d = 0; d < 3; ++d) {
        v[3 * r + d] = u * p[d];
        w[3 * r + d] = 0.0;
    }
}

// v += dv, w += dw with (dv, dw) the 6 values per rod of vel: final_velocities.
extern "C" __global__ void add_velocities(const double* vel, double* v, double* w, int n) {
    int r = blockIdx.x * blockDim.x + threadIdx.x;
    if (r >= n) return;
    for (int d = 0; d < 3; ++d) {
        v[3 * r + d] = v[3 * r + d] + 1.0 * vel[6 * r + d];
        w[3 * r + d] = w[3 * r + d] + 1.0 * vel[6 * r + 3 + d];
    }
}

// dst += 1.0 src over len values (the stepper's axpy: a correction's forces onto the step's).
extern "C" __global__ void add_rows(const double* src, double* dst, int len) {
    int k = blockIdx.x * blockDim.x + threadIdx.x;
    if (k >= len) return;
    dst[k] = dst[k] + 1.0 * src[k];
}

// Each constraint's starting multiplier: the last step's of the same pair (0 where that step
// had none), found by a binary search of its (ci, cj) among the last step's (oi, oj), both
// sorted by (i, j): the stepper's warm start.
extern "C" __global__ void warm_gather(const int* ci, const int* cj, const int* oi,
                                       const int* oj, const double* olam, double* out, int m,
                                       int mo) {
    int k = blockIdx.x * blockDim.x + threadIdx.x;
    if (k >= m) return;
    int a = ci[k], b = cj[k];
    int lo = 0, hi = mo;
    while (lo < hi) {
        int mid = lo + (hi - lo) / 2;
        if (oi[mid] < a || (oi[mid] == a && oj[mid] < b))
            lo = mid + 1;
        else
            hi = mid;
    }
    out[k] = (lo < mo && oi[lo] == a && oj[lo] == b) ? olam[lo] : 0.0;
}

// The overlap projection's move (the stepper's projection round): rod r translated by dt dv
// (dv the first three of its 6 values in vel; move_wrapped), its velocity v += dv and its
// contact force (the first three of its 6 values in ft) += the projection's (pft).
extern "C" __global__ void projection_move(double* x, int* image, const double* vel,
                                           const double* pft, double* v, double* ft, int n,
                                           double dt, double l) {
    int r = blockIdx.x * blockDim.x + threadIdx.x;
    if (r >= n) return;
    move_wrapped(x + 3 * r, image + 3 * r, vel + 6 * r, dt, l);
    for (int d = 0; d < 3; ++d) {
        v[3 * r + d] = v[3 * r + d] + 1.0 * vel[6 * r + d];
        ft[6 * r + d] = ft[6 * r + d] + 1.0 * pft[6 * r + d];
    }
}

// b - |y_i - y_j| of each constrained pair at the rods' present state (true_overlap's terms).
extern "C" __global__ void pair_overlap(const double* x, const double* q, const int* ci,
                                        const int* cj, double* out, int m, double l,
                                        double b) {
    int k = blockIdx.x * blockDim.x + threadIdx.x;
    if (k >= m) return;
    double row[10];
    pair_constraint(x, q, ci[k], cj[k], l, b, 1e300, row);
    out[k] = -row[9];
}

// One rod's terms of the step report: |v|, |w|, whether v and w are finite, the axis, the
// contact force (0 without ft).
struct StatTerms {
    double vn, wn, p[3], f[3];
    bool ok;
};

__device__ StatTerms stat_terms(const double* v, const double* w, const double* q,
                                const double* ft, int r, int has_ft) {
    StatTerms t;
    const double* a = v + 3 * r;
    const double* b = w + 3 * r;
    t.vn = sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
    t.wn = sqrt(b[0] * b[0] + b[1] * b[1] + b[2] * b[2]);
    t.ok = isfinite(a[0]) && isfinite(a[1]) && isfinite(a[2]) && isfinite(b[0]) &&
           isfinite(b[1]) && isfinite(b[2]);
    quat_axis(q + 4 * r, t.p);
    for (int d = 0; d < 3; ++d) t.f[d] = has_ft ? ft[6 * r + d] : 0.0;
    return t;
}

// Per chunk c of `chunk` rods, in order: sum |v| (from -0.0, as the CPU's det_sum), the sums of
// the axes' components, max |v|, max |w| (from 0), the first rod with a non-finite velocity or
// -1, and the sums of the contact forces' components (0 without ft) (10 values at 10 c): the
// step report's partials.
extern "C" __global__ void step_stats(const double* v, const double* w, const double* q,
                                      const double* ft, double* partial, int n, int chunk,
                                      int has_ft) {
    // One block per chunk: its threads compute 256 consecutive rods' terms at a time into
    // shared memory (in parallel), its first thread folds them in order (the one-thread
    // fold's order and bits; computing the terms in that one thread took 4.4 ms per step at
    // L/l = 100).
    __shared__ double sh[8][256];
    __shared__ int sh_ok[256];
    int c = blockIdx.x, t = threadIdx.x;
    if ((long long)c * chunk >= n) return; // the whole block
    int hi = (c + 1) * chunk < n ? (c + 1) * chunk : n;
    double speed = -0.0, p0 = -0.0, p1 = -0.0, p2 = -0.0, vmax = 0.0, wmax = 0.0, bad = -1.0;
    double f0 = -0.0, f1 = -0.0, f2 = -0.0;
    for (int r0 = c * chunk; r0 < hi; r0 += 256) {
        if (r0 + t < hi) {
            StatTerms st = stat_terms(v, w, q, ft, r0 + t, has_ft);
            sh[0][t] = st.vn;
            sh[1][t] = st.wn;
            sh[2][t] = st.p[0];
            sh[3][t] = st.p[1];
            sh[4][t] = st.p[2];
            sh[5][t] = st.f[0];
            sh[6][t] = st.f[1];
            sh[7][t] = st.f[2];
            sh_ok[t] = st.ok ? 1 : 0;
        }
        __syncthreads();
        if (t == 0) {
            int len = hi - r0 < 256 ? hi - r0 : 256;
            for (int u = 0; u < len; ++u) {
                if (bad < 0.0 && !sh_ok[u]) bad = (double)(r0 + u);
                speed += sh[0][u];
                p0 += sh[2][u];
                p1 += sh[3][u];
                p2 += sh[4][u];
                vmax = fmax(vmax, sh[0][u]);
                wmax = fmax(wmax, sh[1][u]);
                if (has_ft) {
                    f0 += sh[5][u];
                    f1 += sh[6][u];
                    f2 += sh[7][u];
                }
            }
        }
        __syncthreads();
    }
    if (t != 0) return;
    double* o = partial + 10 * c;
    o[0] = speed;
    o[1] = p0;
    o[2] = p1;
    o[3] = p2;
    o[4] = vmax;
    o[5] = wmax;
    o[6] = bad;
    o[7] = has_ft ? f0 : 0.0;
    o[8] = has_ft ? f1 : 0.0;
    o[9] = has_ft ? f2 : 0.0;
}
