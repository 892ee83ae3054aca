/*
 * bench_contact: time the three generated contact steps in C, without Python.
 *
 * Used by studies/bench_codegen.py, which builds it with
 * symcushion.compiled.codegen.build_program against the generated symcushion_kernels.o.
 *
 * Usage: bench_contact CASES REPEAT OUT
 *
 *   CASES   binary file of n cases, 22 doubles each, native byte order:
 *           P0 (3), Dp (9, column-major), n (3), l (3), mu (1), u0 (3)
 *   REPEAT  passes over all cases per method; the fastest pass is reported
 *   OUT     binary file receiving, per method (paper, robust, implicit) and
 *           per case, delta (3), P (3), k (3), contact (1): 10 doubles
 *
 * Standard output: one line per method, "name ns_per_eval=...", the best
 * time per evaluation of a pass over all cases measured with
 * clock_gettime(CLOCK_MONOTONIC); the pass calls the Function once per case
 * and does nothing else.
 */
#define _POSIX_C_SOURCE 199309L

#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "symcushion.h"

#define CASE_SIZE 22
#define OUT_SIZE 10

typedef int (*step_fn)(const casadi_real **, casadi_real **, casadi_int *, casadi_real *, int);
typedef int (*work_fn)(casadi_int *, casadi_int *, casadi_int *, casadi_int *);

static double seconds_between(const struct timespec *a, const struct timespec *b)
{
    return (double)(b->tv_sec - a->tv_sec) + 1e-9 * (double)(b->tv_nsec - a->tv_nsec);
}

static int run(const char *name, step_fn f, work_fn work, const double *cases, long n,
               long repeat, double *out)
{
    casadi_int sz_arg, sz_res, sz_iw, sz_w;
    work(&sz_arg, &sz_res, &sz_iw, &sz_w);
    const casadi_real **arg = malloc((size_t)(sz_arg > 0 ? sz_arg : 1) * sizeof *arg);
    casadi_real **res = malloc((size_t)(sz_res > 0 ? sz_res : 1) * sizeof *res);
    casadi_int *iw = malloc((size_t)(sz_iw > 0 ? sz_iw : 1) * sizeof *iw);
    casadi_real *w = malloc((size_t)(sz_w > 0 ? sz_w : 1) * sizeof *w);
    if (!arg || !res || !iw || !w) return 1;
    double best = -1.0;
    long r, i;
    for (r = 0; r < repeat; ++r) {
        struct timespec start, stop;
        clock_gettime(CLOCK_MONOTONIC, &start);
        for (i = 0; i < n; ++i) {
            const double *c = cases + i * CASE_SIZE;
            double *o = out + i * OUT_SIZE;
            arg[0] = c;      /* P0 */
            arg[1] = c + 3;  /* Dp */
            arg[2] = c + 12; /* n */
            arg[3] = c + 15; /* l */
            arg[4] = c + 18; /* mu */
            arg[5] = c + 19; /* u0 */
            res[0] = o;      /* delta */
            res[1] = o + 3;  /* P */
            res[2] = o + 6;  /* k */
            res[3] = o + 9;  /* contact */
            /* mem 0: SX Functions keep no memory, their checkout always returns 0 */
            if (f(arg, res, iw, w, 0)) {
                fprintf(stderr, "bench_contact: %s failed on case %ld.\n", name, i);
                return 1;
            }
        }
        clock_gettime(CLOCK_MONOTONIC, &stop);
        double pass = seconds_between(&start, &stop);
        if (best < 0.0 || pass < best) best = pass;
    }
    printf("%s ns_per_eval=%.6g\n", name, 1e9 * best / (double)n);
    free(arg);
    free(res);
    free(iw);
    free(w);
    return 0;
}

int main(int argc, char *argv[])
{
    if (argc != 4) {
        fprintf(stderr, "usage: bench_contact CASES REPEAT OUT\n");
        return 2;
    }
    long repeat = strtol(argv[2], NULL, 10);
    if (repeat < 1) {
        fprintf(stderr, "bench_contact: REPEAT must be a positive integer, got '%s'.\n", argv[2]);
        return 2;
    }
    FILE *in = fopen(argv[1], "rb");
    if (!in) {
        fprintf(stderr, "bench_contact: cannot read '%s'.\n", argv[1]);
        return 1;
    }
    fseek(in, 0, SEEK_END);
    long bytes = ftell(in);
    fseek(in, 0, SEEK_SET);
    long n = bytes / (long)(CASE_SIZE * sizeof(double));
    double *cases = malloc((size_t)(n > 0 ? n : 1) * CASE_SIZE * sizeof *cases);
    double *out = malloc((size_t)(n > 0 ? n : 1) * 3 * OUT_SIZE * sizeof *out);
    if (n < 1 || !cases || !out
        || fread(cases, sizeof *cases, (size_t)n * CASE_SIZE, in) != (size_t)n * CASE_SIZE) {
        fprintf(stderr, "bench_contact: '%s' holds no whole case of %d doubles.\n", argv[1],
                CASE_SIZE);
        return 1;
    }
    fclose(in);

    contact_step_paper_incref();
    contact_step_robust_incref();
    contact_step_implicit_incref();
    if (run("contact_step_paper", contact_step_paper, contact_step_paper_work, cases, n, repeat,
            out)
        || run("contact_step_robust", contact_step_robust, contact_step_robust_work, cases, n,
               repeat, out + n * OUT_SIZE)
        || run("contact_step_implicit", contact_step_implicit, contact_step_implicit_work, cases,
               n, repeat, out + 2 * n * OUT_SIZE))
        return 1;
    contact_step_paper_decref();
    contact_step_robust_decref();
    contact_step_implicit_decref();

    FILE *fo = fopen(argv[3], "wb");
    if (!fo || fwrite(out, sizeof *out, (size_t)n * 3 * OUT_SIZE, fo) != (size_t)n * 3 * OUT_SIZE
        || fclose(fo) != 0) {
        fprintf(stderr, "bench_contact: cannot write '%s'.\n", argv[3]);
        return 1;
    }
    free(cases);
    free(out);
    return 0;
}
