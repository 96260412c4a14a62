// The tiled gather of the spectral Ewald sums on a GPU (binned.rs gather): appended to
// kernels.cu, whose window functions (window_start, window_weight) and grid layout (grid_row,
// grid_field) it uses. Plain C++ for NVRTC and the emulation, as kernels.cu.

// The tiled gather: one block per bin of the output-driven spreader's sort (bins by the window's
// first index, b^3 cells), each field's tile of t = b + p - 1 cells per axis from the bin's
// first cell (wrapped: on a grid smaller than a tile some cells appear twice) read into shared
// memory once, coalesced, and the bin's points gathered from it: the grid is read about once
// per bin instead of p^3 values per point. GATHER_TILE values of shared memory (32 KB): t <= 16.
#define GATHER_TILE 4096

// Field c of point i from its bin's tile (edge t, first cell ox, oy, oz), as gather_point's
// field c: the same weights and the same sums in the same order, so the same bits.
template <int P>
__device__ void gather_tile_point(const double* pts, const double* tile, double* out, int i,
                                  int n, int c, int gradient, int m, int p_rt, double l,
                                  double h, double alpha, double norm, int t, int ox, int oy,
                                  int oz) {
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
    double a0 = 0.0, ax = 0.0, ay = 0.0, az = 0.0;
    const int lx = f[0] - ox, ly = f[1] - oy, lz = f[2] - oz;
    for (int qz = 0; qz < p; ++qz) {
        double wz = window_weight(d0[2], qz, h, alpha, norm);
        double dwz = 2.0 * alpha * (d0[2] + qz * h) * wz;
        for (int qy = 0; qy < p; ++qy) {
            const double* row = tile + ((lz + qz) * t + (ly + qy)) * t + lx;
            double wy = window_weight(d0[1], qy, h, alpha, norm);
            double dwy = 2.0 * alpha * (d0[1] + qy * h) * wy;
            double wzy = wz * wy;
            double wz_dy = wz * dwy;
            double dz_wy = dwz * wy;
#pragma unroll
            for (int qx = 0; qx < (P > 0 ? P : p); ++qx) {
                double wxq, dwxq;
                if (P > 0) {
                    wxq = wx[qx];
                    dwxq = dwx[qx];
                } else {
                    wxq = window_weight(d0[0], qx, h, alpha, norm);
                    dwxq = 2.0 * alpha * (d0[0] + qx * h) * wxq;
                }
                double g = row[qx];
                a0 += wzy * wxq * g;
                if (gradient) {
                    ax += wzy * dwxq * g;
                    ay += wz_dy * wxq * g;
                    az += dz_wy * wxq * g;
                }
            }
        }
    }
    double h3 = h * h * h;
    out[(long long)c * n + i] = h3 * a0;
    if (gradient) {
        out[(long long)(3 + 3 * c) * n + i] = h3 * ax;
        out[(long long)(3 + 3 * c + 1) * n + i] = h3 * ay;
        out[(long long)(3 + 3 * c + 2) * n + i] = h3 * az;
    }
}

// gather_tile_point with the support compiled in for the supports a tile holds at the smallest
// bins (t = 8 + p - 1 <= 16: p <= 9), at run time for others.
__device__ void gather_tile_any(const double* pts, const double* tile, double* out, int i, int n,
                                int c, int gradient, int m, int p, double l, double h,
                                double alpha, double norm, int t, int ox, int oy, int oz) {
    switch (p) {
#define GATHER_TILE_P(P)                                                                     \
    case P:                                                                                  \
        gather_tile_point<P>(pts, tile, out, i, n, c, gradient, m, P, l, h, alpha, norm, t,  \
                             ox, oy, oz);                                                    \
        return;
        GATHER_TILE_P(4)
        GATHER_TILE_P(5)
        GATHER_TILE_P(6)
        GATHER_TILE_P(7)
        GATHER_TILE_P(8)
        GATHER_TILE_P(9)
#undef GATHER_TILE_P
    default:
        gather_tile_point<0>(pts, tile, out, i, n, c, gradient, m, p, l, h, alpha, norm, t, ox,
                             oy, oz);
    }
}

// Gather three fields (with the window's derivative if gradient) at the points of bin k =
// blockIdx.x (perm[start[k]..start[k + 1]], bins of b^3 cells, nb per axis, sorted by
// bin_count), each field's tile in shared memory; (b + p - 1)^3 <= GATHER_TILE (binned.rs).
extern "C" __global__ void gather_tiles(const double* pts, const double* grid, const int* perm,
                                        const int* start, double* out, int n, int gradient,
                                        int m, int p, double l, double h, double alpha,
                                        double norm, int b, int nb) {
    __shared__ double tile[GATHER_TILE];
    int k = blockIdx.x;
    int s0 = start[k], s1 = start[k + 1];
    if (s0 == s1) return;  // the whole block: no barrier is left waiting
    int ox = (k % nb) * b, oy = ((k / nb) % nb) * b, oz = (k / (nb * nb)) * b;
    int t = b + p - 1;
    long long m3 = grid_field(m), r = grid_row(m);
    for (int c = 0; c < 3; ++c) {
        __syncthreads();  // the previous field's tile is no longer read
        for (int v = threadIdx.x; v < t * t * t; v += blockDim.x) {
            int gx = (ox + v % t) % m, gy = (oy + (v / t) % t) % m, gz = (oz + v / (t * t)) % m;
            tile[v] = grid[c * m3 + ((long long)gz * m + gy) * r + gx];
        }
        __syncthreads();
        for (int j = s0 + threadIdx.x; j < s1; j += blockDim.x)
            gather_tile_any(pts, tile, out, perm[j], n, c, gradient, m, p, l, h, alpha, norm, t,
                            ox, oy, oz);
    }
}
