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
