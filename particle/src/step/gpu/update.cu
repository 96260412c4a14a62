// The rods' update on a GPU: the twin of the stepper's (step/stepper.rs with
// model/rods.rs translate_wrapped and model/geometry.rs quat_exp, quat_mul), one thread per rod.
// Layouts: centres as x, y, z triples, images crossed likewise (ints), quaternions as w, x, y, z,
// velocities and angular velocities as triples.

// Centre x (a triple) moved by dt v, wrapped into [0, l) with the images crossed counted
// (translate_wrapped).
__device__ void move_wrapped(double* x, int* image, const double* v, double dt, double l) {
    for (int d = 0; d < 3; ++d) {
        double dx = dt * v[d];
        double c = x[d] + dx;
        int im = image[d];
        while (c >= l) {
            c -= l;
            ++im;
        }
        while (c < 0.0) {
            c += l;
            --im;
        }
        if (c >= l) {
            c = 0.0;
            ++im;
        }
        x[d] = c;
        image[d] = im;
    }
}

// Centre i moved by dt v (move_wrapped); quaternion i turned by exp(dt w):
// [cos(|a|/2), sin(|a|/2) a/|a|] q with a = dt w.
extern "C" __global__ void rod_update(double* x, int* image, double* q, const double* v,
                                      const double* w, int n, double dt, double l) {
    int i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= n) return;
    move_wrapped(x + 3 * i, image + 3 * i, v + 3 * i, dt, l);
    double a[3] = {dt * w[3 * i], dt * w[3 * i + 1], dt * w[3 * i + 2]};
    double t = sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
    double e[4] = {1.0, 0.0, 0.0, 0.0};
    if (!(t < 1e-300)) {
        double s = sin(0.5 * t) / t;
        e[0] = cos(0.5 * t);
        e[1] = s * a[0];
        e[2] = s * a[1];
        e[3] = s * a[2];
    }
    double b[4] = {q[4 * i], q[4 * i + 1], q[4 * i + 2], q[4 * i + 3]};
    q[4 * i] = e[0] * b[0] - e[1] * b[1] - e[2] * b[2] - e[3] * b[3];
    q[4 * i + 1] = e[0] * b[1] + e[1] * b[0] + e[2] * b[3] - e[3] * b[2];
    q[4 * i + 2] = e[0] * b[2] - e[1] * b[3] + e[2] * b[0] + e[3] * b[1];
    q[4 * i + 3] = e[0] * b[3] + e[1] * b[2] - e[2] * b[1] + e[3] * b[0];
}
