// The spectral Ewald sums on a GPU: the twins of grid.rs (spread,
// the mode multiplication of convolve, gather, gather_gradient) and of the mode functions of
// ewald/kernels.rs (rpy_fourier_mode_screened, the stresslet's force density), and the real-space pair
// sums (spectral/real_space.rs). Compiled by NVRTC, or by the host C++ compiler for the
// emulation (motile-gpu), so: plain C++; shared memory only in kernels that declare it in their
// own body (the emulation runs those with a thread per GPU thread). Each kernel's parameters are
// declared once more in signatures.rs (checked against this file when a device opens it).
//
// Layouts: points as x, y, z triples; point values field-major (field c of point i at
// c n + i); grids in cuFFT's in-place layout: per field M M rows of R = 2 (M/2 + 1) values, x
// fastest (the last R - M of a row unused), and the field's half spectrum, M M (M/2 + 1)
// complex values as (re, im) pairs with the x mode fastest, over the same memory.

#define MAX_SUPPORT 24

// Values of one padded grid row, and of one field (its real values or its half spectrum).
__device__ long long grid_row(int m) { return 2LL * (m / 2 + 1); }
__device__ long long grid_field(int m) { return (long long)m * m * grid_row(m); }

// The window of one point along one axis: the first grid index of its support (in 0..m) and
// the offset d0 of that grid point from the point (in [-w, -w + h)).
__device__ void window_start(double y, double l, int m, int p, double h, int* first,
                             double* d0) {
    double f = y - l * floor(y / l);
    if (f >= l) f = 0.0;
    double t = f / h;
    double i0 = -floor(0.5 * p - t);
    long long fi = ((long long)i0) % m;
    if (fi < 0) fi += m;
    *first = (int)fi;
    *d0 = (i0 - t) * h;
}

// The window's weight at support index q: norm exp(-alpha (d0 + q h)^2).
__device__ double window_weight(double d0, int q, double h, double alpha, double norm) {
    double r = d0 + q * h;
    return norm * exp(-alpha * r * r);
}

// window_start and the p weights (window_weight). As GaussianGrid::prepare_reusing (which
// builds the same exponentials by a recurrence).
__device__ void window_axis(double y, double l, int m, int p, double h, double alpha,
                            double norm, int* first, double* d0, double* w) {
    window_start(y, l, m, p, h, first, d0);
    for (int q = 0; q < p; ++q) w[q] = window_weight(*d0, q, h, alpha, norm);
}

// The first grid index of a point's window along one axis (in 0..m), as window_axis.
__device__ int window_first(double y, double l, int m, int p, double h) {
    double f = y - l * floor(y / l);
    if (f >= l) f = 0.0;
    double i0 = -floor(0.5 * p - f / h);
    long long fi = ((long long)i0) % m;
    if (fi < 0) fi += m;
    return (int)fi;
}

// Spread fields f0..f0 + nf - 1 of point i onto the grids (global atomic adds).
__device__ void spread_point(const double* pts, const double* vals, double* grid, int i, int n,
                             int f0, int nf, int m, int p, double l, double h, double alpha,
                             double norm) {
    int f[3];
    double d0[3];
    double w[3][MAX_SUPPORT];
    for (int d = 0; d < 3; ++d)
        window_axis(pts[3 * i + d], l, m, p, h, alpha, norm, &f[d], &d0[d], w[d]);
    double v[6];
    for (int c = 0; c < nf; ++c) v[c] = vals[(long long)(f0 + c) * n + i];
    long long m3 = grid_field(m), r = grid_row(m);
    for (int qz = 0; qz < p; ++qz) {
        int z = f[2] + qz;
        if (z >= m) z -= m;
        for (int qy = 0; qy < p; ++qy) {
            int y = f[1] + qy;
            if (y >= m) y -= m;
            double wzy = w[2][qz] * w[1][qy];
            long long row = ((long long)z * m + y) * r;
            for (int qx = 0; qx < p; ++qx) {
                int x = f[0] + qx;
                if (x >= m) x -= m;
                double wt = wzy * w[0][qx];
                for (int c = 0; c < nf; ++c)
                    atomicAdd(&grid[(f0 + c) * m3 + row + x], wt * v[c]);
            }
        }
    }
}

// Spread nf fields (nf <= 6) of n points onto nf grids (zeroed by the caller): one thread
// per point in the points' order, global atomic adds (the order of contributions, and so the
// last bits, vary from run to run on a GPU). The slow twin of the binned spreaders below.
extern "C" __global__ void spread(const double* pts, const double* vals, double* grid, int n,
                                  int nf, int m, int p, double l, double h, double alpha,
                                  double norm) {
    int i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= n) return;
    spread_point(pts, vals, grid, i, n, 0, nf, m, p, l, h, alpha, norm);
}

// ---------------------------------------------------------------------------------------------
// Binned spreading, as cuFINUFFT's: the points sorted into bins of b^3 grid points by the first
// index of their window (a counting sort: bin_count, bin_scan, bin_scatter), then either the
// output-driven spreader (spread_cells, the default: each bin's cells summed from the points
// that reach them) or the global-memory spreader run in bin order (spread_sorted) so that
// neighbouring threads add to neighbouring cells. Bins: nb per axis, index (bz nb + by) nb + bx.

// The bin of point i, and its rank among the points of that bin (the counts' old value).
extern "C" __global__ void bin_count(const double* pts, int* bin, int* rank, int* count, int n,
                                     int m, int p, double l, double h, int b, int nb) {
    int i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= n) return;
    int k = 0;
    for (int d = 2; d >= 0; --d) k = k * nb + window_first(pts[3 * i + d], l, m, p, h) / b;
    bin[i] = k;
    rank[i] = atomicAdd(&count[k], 1);
}

// The bins' starts: bin_scan (scan.cu, appended to this source).

// perm[start[bin] + rank] = i: the points in bin order.
extern "C" __global__ void bin_scatter(const int* bin, const int* rank, const int* start,
                                       int* perm, int n) {
    int i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= n) return;
    perm[start[bin[i]] + rank[i]] = i;
}

// The global-memory spreader over the points in bin order (thread j spreads point perm[j]).
extern "C" __global__ void spread_sorted(const double* pts, const double* vals, const int* perm,
                                         double* grid, int n, int nf, int m, int p, double l,
                                         double h, double alpha, double norm) {
    int j = blockIdx.x * blockDim.x + threadIdx.x;
    if (j >= n) return;
    spread_point(pts, vals, grid, perm[j], n, 0, nf, m, p, l, h, alpha, norm);
}

// Each bin's points in ascending point order (one thread per bin, insertion sort): the order
// bin_scatter's atomics gave them varies from run to run; after this it does not, so the
// spreader below sums in the same order in every run.
extern "C" __global__ void bin_order(const int* start, int* perm, int nbins) {
    int k = blockIdx.x * blockDim.x + threadIdx.x;
    if (k >= nbins) return;
    int lo = start[k], hi = start[k + 1];
    for (int a = lo + 1; a < hi; ++a) {
        int v = perm[a], c = a - 1;
        while (c >= lo && perm[c] > v) {
            perm[c + 1] = perm[c];
            --c;
        }
        perm[c + 1] = v;
    }
}

// spread_cells' bins: b^3 grid points, b = 8-10 (binned.rs cell_bin), one block of 256
// threads per bin, CPT = 2-4 cells per thread; the points staged in chunks of CELL_CHUNK in
// shared memory (about 42 KB); at most CELL_NEAR bins reach a bin (a reach of at most 4 per
// axis: ceil(23 / 8) + 1).
#define CELL_CHUNK 64
#define CELL_NEAR 125

// The shared memory of spread_cells (declared in the kernel's own body, as the emulation needs).
struct CellStage {
    double w[CELL_CHUNK][3][MAX_SUPPORT];
    double v[CELL_CHUNK][6];
    int first[CELL_CHUNK][3];
    int lo[CELL_NEAR];
    int at[CELL_NEAR + 1];
};

// The NF fields of the block's two cells per thread: every point whose window covers them, from
// the bins at offsets 0..reach below this one along each axis (bins are by the window's first
// index, so only those reach it). Their points, taken as one list (the bins in a fixed order,
// each bin's points in ascending order), are staged chunk by chunk; each cell sums them in
// that order and is written once: no atomics, the same sum in every run.
template <int NF, int CPT>
__device__ void spread_cells_bin(const double* pts, const double* vals, const int* perm,
                                 const int* start, double* grid, int n, int m, int p, double l,
                                 double h, double alpha, double norm, int b, int nb, int reach,
                                 CellStage* st) {
    int k = blockIdx.x;
    int bin[3] = {k % nb, (k / nb) % nb, k / (nb * nb)};
    int r1 = reach + 1, near = r1 * r1 * r1;
    // The near bins' points: bin t's from st->lo[t], at positions st->at[t].. of the list.
    for (int t = threadIdx.x; t < near; t += blockDim.x) {
        int ox = t % r1, oy = (t / r1) % r1, oz = t / (r1 * r1);
        int src = (((bin[2] - oz + nb) % nb) * nb + (bin[1] - oy + nb) % nb) * nb +
                  (bin[0] - ox + nb) % nb;
        st->lo[t] = start[src];
        st->at[t + 1] = start[src + 1] - start[src];
    }
    __syncthreads();
    if (threadIdx.x == 0) {
        st->at[0] = 0;
        for (int t = 0; t < near; ++t) st->at[t + 1] += st->at[t];
    }
    int cell[CPT][3];
    bool inside[CPT];
    double acc[CPT][NF];
#pragma unroll
    for (int cc = 0; cc < CPT; ++cc) {
        int ci = threadIdx.x + cc * blockDim.x;
        int local[3] = {ci % b, (ci / b) % b, ci / (b * b)};
        inside[cc] = ci < b * b * b;
#pragma unroll
        for (int d = 0; d < 3; ++d) {
            cell[cc][d] = bin[d] * b + local[d];
            inside[cc] = inside[cc] && cell[cc][d] < m;
        }
#pragma unroll
        for (int c = 0; c < NF; ++c) acc[cc][c] = 0.0;
    }
    __syncthreads();
    int total = st->at[near];
    for (int base = 0; base < total; base += CELL_CHUNK) {
        int cnt = total - base < CELL_CHUNK ? total - base : CELL_CHUNK;
        if (base > 0) __syncthreads();
        for (int j = threadIdx.x; j < cnt; j += blockDim.x) {
            int g = base + j, t = 0;
            while (st->at[t + 1] <= g) ++t;
            int i = perm[st->lo[t] + g - st->at[t]];
#pragma unroll
            for (int d = 0; d < 3; ++d) {
                double d0;
                window_axis(pts[3 * i + d], l, m, p, h, alpha, norm, &st->first[j][d], &d0,
                            st->w[j][d]);
            }
#pragma unroll
            for (int c = 0; c < NF; ++c) st->v[j][c] = vals[(long long)c * n + i];
        }
        __syncthreads();
#pragma unroll
        for (int cc = 0; cc < CPT; ++cc) {
            if (!inside[cc]) continue;
            for (int j = 0; j < cnt; ++j) {
                int q[3];
                bool hit = true;
#pragma unroll
                for (int d = 0; d < 3; ++d) {
                    int e = cell[cc][d] - st->first[j][d];
                    if (e < 0) e += m;
                    q[d] = e;
                    hit = hit && e < p;
                }
                if (!hit) continue;
                double wt = st->w[j][2][q[2]] * st->w[j][1][q[1]] * st->w[j][0][q[0]];
#pragma unroll
                for (int c = 0; c < NF; ++c) acc[cc][c] += wt * st->v[j][c];
            }
        }
    }
    long long m3 = grid_field(m), r = grid_row(m);
#pragma unroll
    for (int cc = 0; cc < CPT; ++cc) {
        if (!inside[cc]) continue;
        long long g = ((long long)cell[cc][2] * m + cell[cc][1]) * r + cell[cc][0];
#pragma unroll
        for (int c = 0; c < NF; ++c) grid[c * m3 + g] = acc[cc][c];
    }
}

// The cells per thread of bins of edge b (at most 10: 1 000 cells, 4 per thread).
template <int NF>
__device__ void spread_cells_nf(const double* pts, const double* vals, const int* perm,
                                const int* start, double* grid, int n, int m, int p, double l,
                                double h, double alpha, double norm, int b, int nb, int reach,
                                CellStage* st) {
    int cells = b * b * b;
    if (cells <= 512)
        spread_cells_bin<NF, 2>(pts, vals, perm, start, grid, n, m, p, l, h, alpha, norm, b, nb, reach, st);
    else if (cells <= 768)
        spread_cells_bin<NF, 3>(pts, vals, perm, start, grid, n, m, p, l, h, alpha, norm, b, nb, reach, st);
    else
        spread_cells_bin<NF, 4>(pts, vals, perm, start, grid, n, m, p, l, h, alpha, norm, b, nb, reach, st);
}

// Output-driven spreading (no atomics; every grid value written): nf <= 6 fields of the points
// sorted into bins of b^3 (8 <= b <= 10) by bin_count; reach the bins below a bin along each
// axis whose points can reach it (at most nb - 1, so that no bin is visited twice, and at
// most 4).
extern "C" __global__ void spread_cells(const double* pts, const double* vals, const int* perm,
                                        const int* start, double* grid, int n, int nf, int m,
                                        int p, double l, double h, double alpha, double norm,
                                        int b, int nb, int reach) {
    __shared__ CellStage st;
    switch (nf) {
    case 1: spread_cells_nf<1>(pts, vals, perm, start, grid, n, m, p, l, h, alpha, norm, b, nb, reach, &st); break;
    case 2: spread_cells_nf<2>(pts, vals, perm, start, grid, n, m, p, l, h, alpha, norm, b, nb, reach, &st); break;
    case 3: spread_cells_nf<3>(pts, vals, perm, start, grid, n, m, p, l, h, alpha, norm, b, nb, reach, &st); break;
    case 4: spread_cells_nf<4>(pts, vals, perm, start, grid, n, m, p, l, h, alpha, norm, b, nb, reach, &st); break;
    case 5: spread_cells_nf<5>(pts, vals, perm, start, grid, n, m, p, l, h, alpha, norm, b, nb, reach, &st); break;
    default: spread_cells_nf<6>(pts, vals, perm, start, grid, n, m, p, l, h, alpha, norm, b, nb, reach, &st); break;
    }
}

// Mode s of the half spectrum: its wavenumber, |k|^2, and whether the sums drop it (k = 0 and
// the unpaired Nyquist modes, as GaussianGrid::convolve).
__device__ bool mode_of(long long s, int m, double l, double* k, double* k2) {
    int h0 = m / 2 + 1;
    int i0 = (int)(s % h0);
    long long row = s / h0;
    int i1 = (int)(row % m);
    int i2 = (int)(row / m);
    int idx[3] = {i0, i1, i2};
    double scale = 2.0 * 3.14159265358979323846 / l;
    *k2 = 0.0;
    bool nyquist = false;
    for (int d = 0; d < 3; ++d) {
        int q = idx[d] < (m + 1) / 2 ? idx[d] : idx[d] - m;
        nyquist = nyquist || idx[d] == m / 2;
        k[d] = q * scale;
        *k2 += k[d] * k[d];
    }
    return !nyquist && *k2 != 0.0;
}

// u^ = s(k) (I - k k / k^2) f^ times the window correction h^3 exp(eta k^2 / 4 xi^2), with
// s(k) = (1 + k^2 / 4 xi^2) exp(-k^2 / 4 xi^2) (1 - a^2 k^2 / 6)^2 / (k^2 vol) (mu = 1): the
// RPY kernel of ewald/kernels.rs. Writes the three output spectra of mode s; f the three force
// spectra.
__device__ void rpy_mode(const double* f, double* out, long long s, long long slen,
                         const double* k, double k2, double xi, double a, double l,
                         double eta, double h) {
    double x = k2 / (4.0 * xi * xi);
    double g = 1.0 - a * a * k2 / 6.0;
    double sc = (1.0 + x) * exp(-x) * g * g / k2 / (l * l * l);
    double corr = h * h * h * exp(eta * x);
    double kf_re = (f[0] * k[0] + f[2] * k[1] + f[4] * k[2]) / k2;
    double kf_im = (f[1] * k[0] + f[3] * k[1] + f[5] * k[2]) / k2;
    for (int c = 0; c < 3; ++c) {
        out[2 * (c * slen + s)] = (f[2 * c] - kf_re * k[c]) * sc * corr;
        out[2 * (c * slen + s) + 1] = (f[2 * c + 1] - kf_im * k[c]) * sc * corr;
    }
}

// The RPY Fourier multiplication, in place: three force spectra in, three velocity spectra
// out (each thread reads its mode's inputs before it writes the outputs).
extern "C" __global__ void rpy_modes(double* spectra, int m, double l, double xi, double a,
                                     double eta, double h) {
    const double* input = spectra;
    double* out = spectra;
    long long s = (long long)blockIdx.x * blockDim.x + threadIdx.x;
    long long slen = (long long)m * m * (m / 2 + 1);
    if (s >= slen) return;
    double k[3], k2;
    if (!mode_of(s, m, l, k, &k2)) {
        for (int c = 0; c < 3; ++c) out[2 * (c * slen + s)] = out[2 * (c * slen + s) + 1] = 0.0;
        return;
    }
    double f[6];
    for (int c = 0; c < 3; ++c) {
        f[2 * c] = input[2 * (c * slen + s)];
        f[2 * c + 1] = input[2 * (c * slen + s) + 1];
    }
    rpy_mode(f, out, s, slen, k, k2, xi, a, l, eta, h);
}

// The stresslet Fourier multiplication: five spectra of the trace-free stresslet components
// (xx, yy, xy, xz, yz; zz = -(xx + yy)) in; the force density f^_i = -i sum_j S^_ij k_j; three
// velocity spectra out (a point force's, a = 0), in place of the first three (each thread reads
// its mode's five inputs before it writes). The trace is left out on purpose: an isotropic
// stresslet s I has the force density -i s k, which the projection I - k k / k^2 removes, so
// its grid is not needed (one grid less per sum). The gradient comes from the window's
// derivative in the gather.
extern "C" __global__ void stresslet_modes(double* spectra, int m, double l, double xi,
                                           double eta, double h) {
    const double* input = spectra;
    double* out = spectra;
    long long s = (long long)blockIdx.x * blockDim.x + threadIdx.x;
    long long slen = (long long)m * m * (m / 2 + 1);
    if (s >= slen) return;
    double k[3], k2;
    if (!mode_of(s, m, l, k, &k2)) {
        for (int c = 0; c < 3; ++c) out[2 * (c * slen + s)] = out[2 * (c * slen + s) + 1] = 0.0;
        return;
    }
    const double* xx = input + 2 * s;
    const double* yy = input + 2 * (slen + s);
    const double* xy = input + 2 * (2 * slen + s);
    const double* xz = input + 2 * (3 * slen + s);
    const double* yz = input + 2 * (4 * slen + s);
    double zz_re = -(xx[0] + yy[0]), zz_im = -(xx[1] + yy[1]);
    double re0 = xx[0] * k[0] + xy[0] * k[1] + xz[0] * k[2];
    double im0 = xx[1] * k[0] + xy[1] * k[1] + xz[1] * k[2];
    double re1 = xy[0] * k[0] + yy[0] * k[1] + yz[0] * k[2];
    double im1 = xy[1] * k[0] + yy[1] * k[1] + yz[1] * k[2];
    double re2 = xz[0] * k[0] + yz[0] * k[1] + zz_re * k[2];
    double im2 = xz[1] * k[0] + yz[1] * k[1] + zz_im * k[2];
    // -i (re + i im) = im - i re
    double f[6] = {im0, -re0, im1, -re1, im2, -re2};
    rpy_mode(f, out, s, slen, k, k2, xi, 0.0, l, eta, h);
}

// Gather three fields back to the n points: h^3 sum_grid G(x) g(y - x) at out[c n + i], and
// with gradient != 0 also d/dy_m at out[(3 + 3 c + m) n + i] from the window's derivative
// g'(y - x_q) = 2 alpha (d0 + q h) g (as gather_gradient_point). With a compile-time support
// P > 0 the x axis's weights are computed once into registers (the inner loop unrolled); with
// P = 0 (the support p_rt at run time) each weight is computed where it is used. The y and z
// axes' weights are computed per row. No local memory: every index into the arrays here is
// known once the loops over them are unrolled (the outputs' loop too), so they live in
// registers and the kernels that call this need no stack; the driver reserves a kernel's
// stack for every thread the device can hold (a stack of window weights, 1 248 bytes per
// thread, took 0.34 GB on an H100). The weights are window_weight's values, the sums'
// operations in the same order.
template <int P>
__device__ void gather_point(const double* pts, const double* grid, double* out, int i, int n,
                             int gradient, int m, int p_rt, double l, double h, double alpha,
                             double norm) {
    const int p = P > 0 ? P : p_rt;
    int f[3];
    double d0[3];
    for (int d = 0; d < 3; ++d) window_start(pts[3 * i + d], l, m, p, h, &f[d], &d0[d]);
    double wx[P > 0 ? P : 1], dwx[P > 0 ? P : 1];
    if (P > 0) {
#pragma unroll
        for (int q = 0; q < (P > 0 ? P : 1); ++q) {
            wx[q] = window_weight(d0[0], q, h, alpha, norm);
            dwx[q] = 2.0 * alpha * (d0[0] + q * h) * wx[q];
        }
    }
    double acc[12];
#pragma unroll
    for (int c = 0; c < 12; ++c) acc[c] = 0.0;
    long long m3 = grid_field(m), r = grid_row(m);
    for (int qz = 0; qz < p; ++qz) {
        int z = f[2] + qz;
        if (z >= m) z -= m;
        double wz = window_weight(d0[2], qz, h, alpha, norm);
        double dwz = 2.0 * alpha * (d0[2] + qz * h) * wz;
        for (int qy = 0; qy < p; ++qy) {
            int y = f[1] + qy;
            if (y >= m) y -= m;
            long long row = ((long long)z * m + y) * r;
            double wy = window_weight(d0[1], qy, h, alpha, norm);
            double dwy = 2.0 * alpha * (d0[1] + qy * h) * wy;
            double wzy = wz * wy;
            double wz_dy = wz * dwy;
            double dz_wy = dwz * wy;
#pragma unroll
            for (int qx = 0; qx < (P > 0 ? P : p); ++qx) {
                int x = f[0] + qx;
                if (x >= m) x -= m;
                double wxq, dwxq;
                if (P > 0) {
                    wxq = wx[qx];
                    dwxq = dwx[qx];
                } else {
                    wxq = window_weight(d0[0], qx, h, alpha, norm);
                    dwxq = 2.0 * alpha * (d0[0] + qx * h) * wxq;
                }
#pragma unroll
                for (int c = 0; c < 3; ++c) {
                    double g = grid[c * m3 + row + x];
                    acc[c] += wzy * wxq * g;
                    if (gradient) {
                        acc[3 + 3 * c] += wzy * dwxq * g;
                        acc[3 + 3 * c + 1] += wz_dy * wxq * g;
                        acc[3 + 3 * c + 2] += dz_wy * wxq * g;
                    }
                }
            }
        }
    }
    double h3 = h * h * h;
#pragma unroll
    for (int c = 0; c < 3; ++c) out[(long long)c * n + i] = h3 * acc[c];
    if (gradient) {
#pragma unroll
        for (int c = 3; c < 12; ++c) out[(long long)c * n + i] = h3 * acc[c];
    }
}

// gather_point for point i with the support compiled in for the supports the sums use (4-20:
// window tolerances 3e-2 to 1e-10), at run time for others.
__device__ void gather_any(const double* pts, const double* grid, double* out, int i, int n,
                           int gradient, int m, int p, double l, double h, double alpha,
                           double norm) {
    switch (p) {
#define GATHER_P(P)                                                                          \
    case P:                                                                                  \
        gather_point<P>(pts, grid, out, i, n, gradient, m, P, l, h, alpha, norm);            \
        return;
        GATHER_P(4)
        GATHER_P(5)
        GATHER_P(6)
        GATHER_P(7)
        GATHER_P(8)
        GATHER_P(9)
        GATHER_P(10)
        GATHER_P(11)
        GATHER_P(12)
        GATHER_P(13)
        GATHER_P(14)
        GATHER_P(15)
        GATHER_P(16)
        GATHER_P(17)
        GATHER_P(18)
        GATHER_P(19)
        GATHER_P(20)
#undef GATHER_P
    default:
        gather_point<0>(pts, grid, out, i, n, gradient, m, p, l, h, alpha, norm);
    }
}

extern "C" __global__ void gather(const double* pts, const double* grid, double* out, int n,
                                  int gradient, int m, int p, double l, double h,
                                  double alpha, double norm) {
    int i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= n) return;
    gather_any(pts, grid, out, i, n, gradient, m, p, l, h, alpha, norm);
}

// The gather over the points in bin order (thread j gathers point perm[j]): neighbouring
// threads read neighbouring cells.
extern "C" __global__ void gather_sorted(const double* pts, const double* grid, const int* perm,
                                         double* out, int n, int gradient, int m, int p,
                                         double l, double h, double alpha, double norm) {
    int j = blockIdx.x * blockDim.x + threadIdx.x;
    if (j >= n) return;
    gather_any(pts, grid, out, perm[j], n, gradient, m, p, l, h, alpha, norm);
}

// ---------------------------------------------------------------------------------------------
// The real-space RPY sum (twin of spectral/real_space.rs rpy_real with ewald/kernels.rs RealSpaceTable and
// rpy_overlap_correction): per target, every point of another group within the cutoff,
// A f + (B / r^2)(r . f) r, and the error model's weighted strengths. Points in cell order
// (point_cells.rs: positions wrapped into [0, L), cells of side >= cutoff / 2, x fastest).

// Minimum image of a difference of two wrapped positions.
__device__ double min_image_wrapped(double c, double l) {
    double h = 0.5 * l;
    if (c > h) return c - l;
    if (c < -h) return c + l;
    return c;
}

// Cubic Lagrange interpolation on a uniform table of nt intervals at x = r / h (ewald/kernels.rs
// lagrange4): the first of the four nodes, and their weights in w.
__device__ long long lagrange4(double x, int nt, double* w) {
    long long i = (long long)x;
    i = i > 0 ? i - 1 : 0;
    if (i > nt - 3) i = nt - 3;
    double t = x - (double)i;
    double t1 = t - 1.0, t2 = t - 2.0, t3 = t - 3.0;
    const double SIXTH = 1.0 / 6.0;
    w[0] = -t1 * t2 * t3 * SIXTH;
    w[1] = t * t2 * t3 * 0.5;
    w[2] = -t * t1 * t3 * 0.5;
    w[3] = t * t1 * t2 * SIXTH;
    return i;
}

// One source j at offset r from the target: the table's (A, B / r^2) and the overlap
// correction, added to acc (three velocity components and the weighted strength).
__device__ void rpy_pair(const double* r, const double* f, double f2, const double* table,
                         int nt, double inv_h, double c, double ca, double cb, double a,
                         double r0sq, double* acc) {
    double r2 = r[0] * r[0] + r[1] * r[1] + r[2] * r[2];
    double rn = sqrt(r2);
    double inv = 1.0 / rn;
    double w[4];
    const double* g = table + 2 * lagrange4(rn * inv_h, nt, w);
    double af = w[0] * g[0] + w[1] * g[2] + w[2] * g[4] + w[3] * g[6];
    double bf = w[0] * g[1] + w[1] * g[3] + w[2] * g[5] + w[3] * g[7];
    double inv2 = inv * inv;
    double inv3 = inv2 * inv;
    double ar = c * inv + ca * inv3 - af;
    double br2 = (c - cb * inv2) * inv3 - bf;
    if (rn < 2.0 * a) {
        const double PI = 3.14159265358979323846;
        double co = 1.0 / (6.0 * PI * a);
        double ao = co * (1.0 - 9.0 * rn / (32.0 * a));
        double bo = co * 3.0 * rn / (32.0 * a);
        double rr3 = rn * rn * rn, a2 = a * a;
        double afar = (1.0 / rn + 2.0 * a2 / (3.0 * rr3)) / (8.0 * PI);
        double bfar = (1.0 / rn - 2.0 * a2 / rr3) / (8.0 * PI);
        ar += ao - afar;
        br2 += (bo - bfar) / (rn * rn);
    }
    double s = br2 * (r[0] * f[0] + r[1] * f[1] + r[2] * f[2]);
    for (int d = 0; d < 3; ++d) acc[d] += ar * f[d] + s * r[d];
    acc[3] += r0sq / (r0sq + rn * rn) * f2;
}

// Every source j of another group within the cutoff of target t (cell order): pair(j, r)
// with r the minimum-image offset target minus source. Few cells (fewer than five per axis):
// every point; else the 5^3 stencil of cells around the target's. Inlined, so that the pair's
// accumulators stay in registers (a pair passed to a call lives in local memory: a stack).
template <typename Pair>
__device__ __forceinline__ void for_each_neighbour(int t, const double* pos, const int* group,
                                   const int* start, int npts, int ncell, double l,
                                   double cutoff, Pair& pair) {
    double yt[3] = {pos[3 * t], pos[3 * t + 1], pos[3 * t + 2]};
    int gt = group[t];
    double c2 = cutoff * cutoff;
    if (ncell < 5) {
        for (int j = 0; j < npts; ++j) {
            double r[3];
            for (int d = 0; d < 3; ++d) r[d] = min_image_wrapped(yt[d] - pos[3 * j + d], l);
            double r2 = r[0] * r[0] + r[1] * r[1] + r[2] * r[2];
            if (r2 < c2 && r2 > 0.0 && group[j] != gt) pair(j, r, r2);
        }
        return;
    }
    double scale = ncell / l;
    int cell[3];
    for (int d = 0; d < 3; ++d) {
        // Clamped at both ends, as PointCells::build's `as usize` and `min` do (a wrapped
        // coordinate can come out a rounding error below 0).
        int k = (int)(yt[d] * scale);
        cell[d] = k < 0 ? 0 : (k < ncell - 1 ? k : ncell - 1);
    }
    for (int dz = -2; dz <= 2; ++dz) {
        int z = cell[2] + dz;
        double sz = z < 0 ? -l : (z >= ncell ? l : 0.0);
        z = (z + ncell) % ncell;
        for (int dy = -2; dy <= 2; ++dy) {
            int y = cell[1] + dy;
            double sy = y < 0 ? -l : (y >= ncell ? l : 0.0);
            y = (y + ncell) % ncell;
            for (int dx = -2; dx <= 2; ++dx) {
                int x = cell[0] + dx;
                double sx = x < 0 ? -l : (x >= ncell ? l : 0.0);
                x = (x + ncell) % ncell;
                long long cc = ((long long)z * ncell + y) * ncell + x;
                long long j0 = (long long)start[cc], j1 = (long long)start[cc + 1];
                if (j1 > npts) j1 = npts; // the starts are the caller's; stay inside pos
                // The target shifted by the cell's image, then the source: the CPU's
                // (y_t - s) - y_j.
                double ys[3] = {yt[0] - sx, yt[1] - sy, yt[2] - sz};
                for (long long j = j0; j < j1; ++j) {
                    double r[3] = {ys[0] - pos[3 * j], ys[1] - pos[3 * j + 1],
                                   ys[2] - pos[3 * j + 2]};
                    double r2 = r[0] * r[0] + r[1] * r[1] + r[2] * r[2];
                    if (r2 < c2 && r2 > 0.0 && group[j] != gt) pair((int)j, r, r2);
                }
            }
        }
    }
}

struct RpyPair {
    const double* force;
    const double* table;
    int nt;
    double inv_h, c, ca, cb, a, r0sq;
    double acc[4];
    __device__ __forceinline__ void operator()(int j, const double* r, double) {
        const double* f = force + 3 * j;
        rpy_pair(r, f, f[0] * f[0] + f[1] * f[1] + f[2] * f[2], table, nt, inv_h, c, ca, cb, a,
                 r0sq, acc);
    }
};

// Per target t (cell order): pos, force 3 per point, group and cell starts (ints), table
// 2 (nt + 1) values (A_F, B_F / r^2 at r = k h); out 4 per point.
extern "C" __global__ void rpy_real(const double* pos, const double* force, const int* group,
                                    const int* start, const double* table, double* out,
                                    int npts, int ncell, int nt, double l, double cutoff,
                                    double inv_h, double c, double ca, double cb, double a,
                                    double r0sq) {
    int t = blockIdx.x * blockDim.x + threadIdx.x;
    if (t >= npts) return;
    RpyPair pair{force, table, nt, inv_h, c, ca, cb, a, r0sq, {0.0, 0.0, 0.0, 0.0}};
    for_each_neighbour(t, pos, group, start, npts, ncell, l, cutoff, pair);
    for (int d = 0; d < 4; ++d) out[4 * t + d] = pair.acc[d];
}

// ---------------------------------------------------------------------------------------------
// The real-space stresslet sum (twin of spectral/real_space.rs stresslet_real with ewald/kernels.rs
// StressletTable and stresslet_from_derivatives): per target, velocity, gradient and the
// error model's weighted strengths of every other stresslet within the cutoff.

// The Stokeslet's real-space radial derivatives [A, A', A'', C, C', C''] in closed form.
__device__ void stokeslet_real_derivatives(double r, double xi, double* d) {
    const double PI = 3.14159265358979323846;
    const double PI_3_2 = 5.568327996831708; // pi^(3/2)
    double r2 = r * r, x2 = xi * xi;
    double ec = erfc(xi * r) / PI;
    double g = xi * exp(-x2 * r2) / PI_3_2;
    double r3 = r2 * r, r4 = r2 * r2;
    d[0] = ec / (8.0 * r) - g / 4.0;
    d[1] = g * x2 * r / 2.0 - g / (4.0 * r) - ec / (8.0 * r2);
    d[2] = g * x2 * (1.0 - r2 * x2) + g / (2.0 * r2) + ec / (4.0 * r3);
    d[3] = g / (4.0 * r2) + ec / (8.0 * r3);
    d[4] = -g * x2 / (2.0 * r) - 3.0 * g / (4.0 * r3) - 3.0 * ec / (8.0 * r4);
    d[5] = g * (x2 * x2 + 2.0 * x2 / r2 + 3.0 / r4) + 3.0 * ec / (2.0 * r4 * r);
}

// The strengths: sigma[j] per point (PER_POINT), or one strength for all (sigma_all). A
// choice at compile time: one made at run time (`sigma ? sigma[j] : sigma_all`) becomes a load
// through a pointer to either, which keeps sigma_all in local memory (a stack).
template <bool PER_POINT>
struct StressletPair {
    const double* orient;
    const double* sigma;
    double sigma_all;
    const double* table;
    int nt;
    double inv_h, xi, r_direct, r0sq;
    double acc[13];
    __device__ __forceinline__ void operator()(int j, const double* x, double r2) {
        double r = sqrt(r2);
        double d[6];
        if (r < r_direct) {
            stokeslet_real_derivatives(r, xi, d);
            d[0] = 0.0;
        } else {
            // The table's Fourier part subtracted from the free-space Stokeslet.
            double w[4];
            const double* g = table + 5 * lagrange4(r * inv_h, nt, w);
            const double PI = 3.14159265358979323846;
            double cf = 1.0 / (8.0 * PI);
            double i1 = 1.0 / r, i2 = i1 * i1, i3 = i2 * i1;
            double f[6] = {cf * i1, -cf * i2, 2.0 * cf * i3, cf * i3, -3.0 * cf * i3 * i1,
                           12.0 * cf * i3 * i2};
            d[0] = 0.0;
            for (int c = 0; c < 5; ++c) {
                double v = w[0] * g[c] + w[1] * g[5 + c] + w[2] * g[10 + c] + w[3] * g[15 + c];
                d[c + 1] = f[c + 1] - v;
            }
        }
        const double* p = orient + 3 * j;
        double s = PER_POINT ? sigma[j] : sigma_all;
        double a1r = d[1], a2r = d[2], c = d[3], c1r = d[4], c2r = d[5];
        double q = p[0] * x[0] + p[1] * x[1] + p[2] * x[2];
        double inv = 1.0 / r;
        double a1 = a1r * inv, c1 = c1r * inv;
        double a1p = (a2r - a1) * inv, c1p = (c2r - c1) * inv;
        double vp = (a1 + c) * q;
        double vx = c1 * q * q + c;
#pragma unroll
        for (int i = 0; i < 3; ++i) acc[i] += -s * (vp * p[i] + vx * x[i]);
        double ap = (a1p + c1r) * q * inv;
        double bx = (c1p * q * q + c1r) * inv;
#pragma unroll
        for (int i = 0; i < 3; ++i)
#pragma unroll
            for (int m = 0; m < 3; ++m) {
                double v = p[i] * (ap * x[m] + (a1 + c) * p[m]) +
                           x[i] * (bx * x[m] + 2.0 * c1 * q * p[m]) + (i == m ? vx : 0.0);
                acc[3 + 3 * i + m] += -s * v;
            }
        acc[12] += r0sq / (r0sq + r2) * s * s;
    }
};

// Per target t (cell order): pos and orient 3 per point, sigma, group and cell starts (ints), table
// 5 (nt + 1) values ([A', A'', C, C', C''] of the Fourier part at r = k h); out 13 per point
// (velocity, gradient d u_i / d x_m at 3 + 3 i + m, weighted strengths).
extern "C" __global__ void stresslet_real(const double* pos, const double* orient,
                                          const double* sigma, const int* group,
                                          const int* start, const double* table, double* out,
                                          int npts, int ncell, int nt, double l, double cutoff,
                                          double inv_h, double xi, double r_direct,
                                          double r0sq) {
    int t = blockIdx.x * blockDim.x + threadIdx.x;
    if (t >= npts) return;
    StressletPair<true> pair{orient, sigma, 0.0, table, nt, inv_h, xi, r_direct, r0sq, {}};
    for_each_neighbour(t, pos, group, start, npts, ncell, l, cutoff, pair);
    for (int k = 0; k < 13; ++k) out[13 * t + k] = pair.acc[k];
}
