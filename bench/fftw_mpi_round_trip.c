/* FFTW's MPI interface on the measurement of experiments/examples/mpi_fft.rs: for each grid
 * size M, 10 round trips (forward r2c, then inverse c2r) of three real fields on M^3, slab
 * decomposition along the first axis, transposed output/input (FFTW's fastest MPI mode: no
 * transpose back), planned with FFTW_MEASURE, one thread per rank. Prints M, the ranks, the
 * median seconds per round trip (the slowest rank's) and the round trip's largest relative
 * error. For BENCHMARKS.md ("Several ranks"); not part of motile (FFTW is GPL).
 *
 *   apt-get install libfftw3-mpi-dev
 *   mpicc -O3 -o /tmp/fftw_mpi_round_trip bench/fftw_mpi_round_trip.c -lfftw3_mpi -lfftw3 -lm
 *   mpirun -n P /tmp/fftw_mpi_round_trip [M ...]      # default 64 128
 */
#include <fftw3-mpi.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#define FIELDS 3
#define REPS 10

/* The test field: a deterministic value of the global index g and the field f, in [-0.5, 0.5),
 * the same as motile's fft_round_trip. */
static double value(size_t g, int f) {
    double v = (g * 7 + f * 13) * 0.6180339887;
    return v - floor(v) - 0.5;
}

static int cmp(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

int main(int argc, char **argv) {
    MPI_Init(&argc, &argv);
    fftw_mpi_init();
    int rank, size;
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    MPI_Comm_size(MPI_COMM_WORLD, &size);
    int nsizes = argc > 1 ? argc - 1 : 2;
    if (rank == 0) printf("impl,ranks,M,seconds_per_round_trip,max_relative_error\n");
    for (int s = 0; s < nsizes; s++) {
        ptrdiff_t m = argc > 1 ? atol(argv[s + 1]) : (s == 0 ? 64 : 128);
        ptrdiff_t n[3] = {m, m, m};
        ptrdiff_t local_n0, start0, local_n1, start1;
        ptrdiff_t alloc = fftw_mpi_local_size_many_transposed(
            3, (ptrdiff_t[]){m, m, m / 2 + 1}, FIELDS, FFTW_MPI_DEFAULT_BLOCK,
            FFTW_MPI_DEFAULT_BLOCK, MPI_COMM_WORLD, &local_n0, &start0, &local_n1, &start1);
        double *real = fftw_alloc_real(2 * alloc);
        fftw_complex *spec = fftw_alloc_complex(alloc);
        fftw_plan fwd = fftw_mpi_plan_many_dft_r2c(
            3, n, FIELDS, FFTW_MPI_DEFAULT_BLOCK, FFTW_MPI_DEFAULT_BLOCK, real, spec,
            MPI_COMM_WORLD, FFTW_MEASURE | FFTW_MPI_TRANSPOSED_OUT);
        fftw_plan inv = fftw_mpi_plan_many_dft_c2r(
            3, n, FIELDS, FFTW_MPI_DEFAULT_BLOCK, FFTW_MPI_DEFAULT_BLOCK, spec, real,
            MPI_COMM_WORLD, FFTW_MEASURE | FFTW_MPI_TRANSPOSED_IN);
        /* Real layout: [local x0][x1][2 (M/2 + 1) padded][field]. */
        ptrdiff_t pad = 2 * (m / 2 + 1);
        double times[REPS], err = 0.0;
        for (int r = 0; r < REPS; r++) {
            for (ptrdiff_t i = 0; i < local_n0; i++)
                for (ptrdiff_t j = 0; j < m; j++)
                    for (ptrdiff_t k = 0; k < m; k++)
                        for (int f = 0; f < FIELDS; f++) {
                            size_t g = (size_t)(((start0 + i) * m + j) * m + k);
                            real[((i * m + j) * pad + k) * FIELDS + f] = value(g, f);
                        }
            MPI_Barrier(MPI_COMM_WORLD);
            double t = MPI_Wtime();
            fftw_execute(fwd);
            fftw_execute(inv);
            times[r] = MPI_Wtime() - t;
            double scale = 1.0 / ((double)m * m * m);
            for (ptrdiff_t i = 0; i < local_n0; i++)
                for (ptrdiff_t j = 0; j < m; j++)
                    for (ptrdiff_t k = 0; k < m; k++)
                        for (int f = 0; f < FIELDS; f++) {
                            size_t g = (size_t)(((start0 + i) * m + j) * m + k);
                            double x = real[((i * m + j) * pad + k) * FIELDS + f] * scale;
                            double e = fabs(x - value(g, f)) / 0.5;
                            if (e > err) err = e;
                        }
        }
        qsort(times, REPS, sizeof(double), cmp);
        double worst[2] = {times[REPS / 2], err}, out[2];
        MPI_Reduce(worst, out, 2, MPI_DOUBLE, MPI_MAX, 0, MPI_COMM_WORLD);
        if (rank == 0) printf("fftw,%d,%td,%.6f,%.1e\n", size, m, out[0], out[1]);
        fftw_destroy_plan(fwd);
        fftw_destroy_plan(inv);
        fftw_free(real);
        fftw_free(spec);
    }
    fftw_mpi_cleanup();
    MPI_Finalize();
    return 0;
}
