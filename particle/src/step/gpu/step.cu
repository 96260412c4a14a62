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
