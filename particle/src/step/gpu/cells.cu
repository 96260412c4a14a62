// The cell list and the neighbour pairs of the rods' centres on a GPU: the twins of
// step/cells.rs (CellList::build and its pairs). Compiled by NVRTC, or by the host C++ compiler
// for the emulation (motile-gpu), with scan.cu's prefix sum (bin_scan) appended.
//
// Layouts: centres as x, y, z triples in [0, L)^3; cells nc per axis, index (z nc + y) nc + x,
// of side L / nc >= the cutoff, nc >= 3 (so the 27 cells around a cell are distinct and the
// periodic shift of a neighbour cell is the minimum image of every pair within the cutoff).
// Pairs (i, j), i < j, as two ints, sorted by i then j: the same list for any launch order.

// The cell of centre i (as CellList::build: floor(x / L nc), at most nc - 1) and the cells'
// counts (zeroed by the caller).
extern "C" __global__ void cell_count(const double* x, int* cell, int* count, int n, int nc,
                                      double l) {
    int i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= n) return;
    int k = 0;
    for (int d = 2; d >= 0; --d) {
        int c = (int)(x[3 * i + d] / l * nc);
        if (c < 0) c = 0;
        if (c > nc - 1) c = nc - 1;
        k = k * nc + c;
    }
    cell[i] = k;
    atomicAdd(&count[k], 1);
}

// members[start[cell] + r] = i with r the centre's rank by an atomic (fill zeroed by the
// caller); cell_order then puts each cell's members in increasing index.
extern "C" __global__ void cell_scatter(const int* cell, const int* start, int* fill,
                                        int* members, int n) {
    int i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= n) return;
    int k = cell[i];
    members[start[k] + atomicAdd(&fill[k], 1)] = i;
}

// Insertion sort of ints a[0..len).
__device__ void sort_ints(int* a, int len) {
    for (int s = 1; s < len; ++s) {
        int v = a[s];
        int t = s - 1;
        while (t >= 0 && a[t] > v) {
            a[t + 1] = a[t];
            --t;
        }
        a[t + 1] = v;
    }
}

// Each cell's members in increasing index: the order CellList::build's stable counting sort
// gives, whatever order the atomics of cell_scatter took.
extern "C" __global__ void cell_order(const int* start, int* members, int ncells) {
    int c = blockIdx.x * blockDim.x + threadIdx.x;
    if (c >= ncells) return;
    sort_ints(members + start[c], start[c + 1] - start[c]);
}

// The neighbours j > i of centre i closer than sqrt(c2) (27-cell stencil, the neighbour cell's
// periodic shift as CellList::map_pairs), written to js if it is not null; their number.
__device__ int neighbours(const double* x, const int* cell, const int* start,
                          const int* members, int i, int nc, double l, double c2, int* js) {
    int k = cell[i];
    int own[3] = {k % nc, (k / nc) % nc, k / (nc * nc)};
    double xi[3] = {x[3 * i], x[3 * i + 1], x[3 * i + 2]};
    int found = 0;
    for (int dz = -1; dz <= 1; ++dz) {
        for (int dy = -1; dy <= 1; ++dy) {
            for (int dx = -1; dx <= 1; ++dx) {
                int raw[3] = {own[0] + dx, own[1] + dy, own[2] + dz};
                int w[3];
                double shift[3];
                for (int d = 0; d < 3; ++d) {
                    w[d] = ((raw[d] % nc) + nc) % nc;
                    shift[d] = l * (double)((raw[d] - w[d]) / nc);
                }
                int c = (w[2] * nc + w[1]) * nc + w[0];
                for (int s = start[c]; s < start[c + 1]; ++s) {
                    int j = members[s];
                    if (j <= i) continue;
                    double d0 = x[3 * j] + shift[0] - xi[0];
                    double d1 = x[3 * j + 1] + shift[1] - xi[1];
                    double d2 = x[3 * j + 2] + shift[2] - xi[2];
                    if (d0 * d0 + d1 * d1 + d2 * d2 < c2) {
                        if (js) js[found] = j;
                        ++found;
                    }
                }
            }
        }
    }
    return found;
}

// How many neighbours j > i each centre has.
extern "C" __global__ void pair_count(const double* x, const int* cell, const int* start,
                                      const int* members, int* counts, int n, int nc, double l,
                                      double c2) {
    int i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= n) return;
    counts[i] = neighbours(x, cell, start, members, i, nc, l, c2, 0);
}

// The pairs of centre i at offset[i] (the counts' prefix sum), its j in increasing order.
extern "C" __global__ void pair_write(const double* x, const int* cell, const int* start,
                                      const int* members, const int* offset, int* first,
                                      int* second, int n, int nc, double l, double c2) {
    int i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= n) return;
    int o = offset[i];
    int found = neighbours(x, cell, start, members, i, nc, l, c2, second + o);
    sort_ints(second + o, found);
    for (int s = 0; s < found; ++s) first[o + s] = i;
}
