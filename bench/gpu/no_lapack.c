/* no_lapack.c - the one LAPACK routine the codec's package code names
 * (LAPACKE_dposv, in the residual-level writer's least-squares solve,
 * codec/format/btf_lap.c), for the GPU bench folder: that build only reads
 * packages made beforehand, so the solve is unreachable there; should it run, it
 * fails (LAPACK's "illegal argument" code), and the writer reports the failure. The
 * folder then carries no LAPACK, BLAS or Fortran runtime (about 50 MB). */
#include <stdio.h>

int LAPACKE_dposv(int layout, char uplo, int n, int nrhs, double *a, int lda, double *b, int ldb);

int LAPACKE_dposv(int layout, char uplo, int n, int nrhs, double *a, int lda, double *b, int ldb)
{
    (void)layout, (void)uplo, (void)n, (void)nrhs, (void)a, (void)lda, (void)b, (void)ldb;
    fprintf(stderr, "bench_shader: LAPACK is not in the GPU bench folder (it reads packages only)\n");
    return -1;
}
