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
// each clamped to nc - 1 as PointCells::build) and its rank among the cell's points (the
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
        if (c > nc - 1) c = nc - 1;
        k = k * nc + c;
    }
    cell[i] = k;
    rank[i] = atomicAdd(&count[k], 1);
}

// rows_out[k] = rows_in[idx[k]], width values per row: the points' values in cell order
// (idx the cells' members).
extern "C" __global__ void take_rows(const double* rows_in, const int* idx, double* rows_out,
                                     int n, int width) {
    int k = blockIdx.x * blockDim.x + threadIdx.x;
    if (k >= n) return;
    long long from = (long long)idx[k] * width, to = (long long)k * width;
    for (int c = 0; c < width; ++c) rows_out[to + c] = rows_in[from + c];
}

// rows_out[idx[k]] = rows_in[k]: values in cell order back to the points' order.
extern "C" __global__ void put_rows(const double* rows_in, const int* idx, double* rows_out,
                                    int n, int width) {
    int k = blockIdx.x * blockDim.x + threadIdx.x;
    if (k >= n) return;
    long long from = (long long)k * width, to = (long long)idx[k] * width;
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

// The six stresslet components sigma p_i p_j (xx, yy, zz, xy, xz, yz), field-major, and each
// point's strength.
extern "C" __global__ void stresslet_values(const double* p, double sigma, double* vals,
                                            double* strength, int n) {
    int t = blockIdx.x * blockDim.x + threadIdx.x;
    if (t >= n) return;
    const double* pt = p + 3 * t;
    const int I[6] = {0, 1, 2, 0, 0, 1}, J[6] = {0, 1, 2, 1, 2, 2};
    for (int c = 0; c < 6; ++c) vals[(long long)c * n + t] = sigma * pt[I[c]] * pt[J[c]];
    strength[t] = sigma;
}

// The stresslet sum per point t: velocity (real + Fourier) / mu into u (triples), gradient
// (real + Fourier - the Fourier part's own term own_c (p p - I/3), own_c from sigma) / mu into grad (9 per point,
// du_i/dx_m at 3 i + m), and the error model's inputs into parts (4 per point: weighted
// strengths, |u|^2, weighted strengths + sigma^2, |grad u|^2). real: 13 per point in the
// points' order; back: 12 fields of n values (velocity, then du_i/dx_m at 3 + 3 i + m).
extern "C" __global__ void stresslet_assemble(const double* real, const double* back,
                                              const double* p, double* u, double* grad,
                                              double* parts, int n, double sigma,
                                              double own_c, double mu) {
    int t = blockIdx.x * blockDim.x + threadIdx.x;
    if (t >= n) return;
    const double* r = real + 13 * (long long)t;
    const double* pt = p + 3 * t;
    double u2 = 0.0, g2 = 0.0;
    for (int i = 0; i < 3; ++i) {
        double v = (r[i] + back[(long long)i * n + t]) / mu;
        u[3 * t + i] = v;
        u2 += v * v;
    }
    for (int i = 0; i < 3; ++i) {
        double row = 0.0;
        for (int m = 0; m < 3; ++m) {
            double own = own_c * (pt[i] * pt[m] - (i == m ? 1.0 / 3.0 : 0.0));
            double v = (r[3 + 3 * i + m] + back[(long long)(3 + 3 * i + m) * n + t] - own) / mu;
            grad[9 * t + 3 * i + m] = v;
            row += v * v;
        }
        g2 += row;
    }
    double e2 = r[12];
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
    int c = blockIdx.x * blockDim.x + threadIdx.x;
    int nchunks = (n + chunk - 1) / chunk;
    if (c >= nchunks) return;
    int hi = (c + 1) * chunk < n ? (c + 1) * chunk : n;
    for (int o = 0; o < nout; ++o) {
        double a_max = w[3 * o], a_2 = w[3 * o + 1], far = w[3 * o + 2];
        double acc[4] = {0.0, 0.0, 0.0, 0.0};
        for (int t = c * chunk; t < hi; ++t) {
            double e = parts[(long long)2 * nout * t + 2 * o];
            double q = parts[(long long)2 * nout * t + 2 * o + 1];
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
