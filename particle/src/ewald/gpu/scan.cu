// An exclusive prefix sum in one block, shared by the kernel sets of the particle crate (the
// binned spreaders' bins, the device cell lists and neighbour pairs): appended to their sources.

// Exclusive prefix sum of the nbins counts into start (nbins + 1 values, the last the total):
// one block; each thread sums a contiguous chunk, the chunk totals are scanned in shared
// memory, then each thread writes its chunk's starts.
extern "C" __global__ void bin_scan(const int* count, int* start, int nbins) {
    __shared__ int total[256];
    int t = threadIdx.x;
    int chunk = (nbins + blockDim.x - 1) / blockDim.x;
    int lo = t * chunk, hi = lo + chunk < nbins ? lo + chunk : nbins;
    int s = 0;
    for (int k = lo; k < hi; ++k) s += count[k];
    total[t] = s;
    __syncthreads();
    if (t == 0) {
        int run = 0;
        for (int u = 0; u < (int)blockDim.x; ++u) {
            int v = total[u];
            total[u] = run;
            run += v;
        }
        start[nbins] = run;
    }
    __syncthreads();
    int run = total[t];
    for (int k = lo; k < hi; ++k) {
        start[k] = run;
        run += count[k];
    }
}

// The same prefix sum for many values in three launches (prefix_sum in ewald/gpu/binned.rs and
// step/gpu/device.rs): scan_tiles sums each tile of `tile` counts (one thread per tile),
// bin_scan scans the tiles' sums, scan_spread writes each tile's starts from its tile's start.
// Integer sums: the same values as bin_scan's alone, in any launch order.
extern "C" __global__ void scan_tiles(const int* count, int* sums, int nbins, int tile) {
    int t = blockIdx.x * blockDim.x + threadIdx.x;
    long long lo = (long long)t * tile;
    if (lo >= nbins) return;
    long long hi = lo + tile < nbins ? lo + tile : nbins;
    int s = 0;
    for (long long k = lo; k < hi; ++k) s += count[k];
    sums[t] = s;
}

extern "C" __global__ void scan_spread(const int* count, const int* tile_start, int* start,
                                       int nbins, int tile) {
    int t = blockIdx.x * blockDim.x + threadIdx.x;
    long long lo = (long long)t * tile;
    if (lo >= nbins) return;
    long long hi = lo + tile < nbins ? lo + tile : nbins;
    int run = tile_start[t];
    for (long long k = lo; k < hi; ++k) {
        start[k] = run;
        run += count[k];
    }
    if (hi == nbins) start[nbins] = run;
}
