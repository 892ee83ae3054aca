/*
 * touchdown: a scene's touchdown simulated by the generated touchdown_step,
 * without Python.
 *
 * `symcushion codegen --scene SCENE.toml --out DIR --build` compiles this file
 * with DIR/symcushion_gen*.c (the CasADi-generated Functions, declared in
 * DIR/symcushion.h) and DIR/scene_data.h (the scene's initial state x0,
 * parameters p, time step dt and number of steps N, written by
 * symcushion.compiled.codegen) into DIR/touchdown; docs/codegen.md gives the command.
 *
 * Usage: touchdown [-n STEPS] [-d DT] [-r REPEAT] [-o FILE]
 *
 *   -n STEPS   number of steps (default: the scene's duration/dt)
 *   -d DT      time step in s (default: the scene's dt)
 *   -r REPEAT  run the step loop REPEAT times from x0 and report the fastest
 *              (default 1); the trajectory written is that of the last loop,
 *              identical in every loop
 *   -o FILE    write the CSV to FILE instead of standard output
 *
 * Output: CSV with a header line "t,<state names>" and N + 1 rows, row k
 * holding t = k*dt and the state after k steps (row 0: x0), every number
 * printed with 17 significant digits so that it reads back to the same
 * double. On standard error one line of key=value pairs reports the time of
 * the step loop measured with clock_gettime(CLOCK_MONOTONIC): the loop
 * calls touchdown_step N times and copies nothing else; writing the CSV is
 * outside it.
 *
 * The state lives in one array of (N + 1) * nx doubles, step k reading row k
 * and writing row k + 1: the generated code reads its inputs while it writes
 * its outputs, so x and x_next must not alias.
 */
#define _POSIX_C_SOURCE 199309L

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "symcushion.h"
#include "scene_data.h"

static void usage(FILE *out)
{
    fprintf(out, "usage: touchdown [-n STEPS] [-d DT] [-r REPEAT] [-o FILE]\n"
                 "Simulate scene '%s' (%d steps of %g s by default); CSV to stdout.\n",
            SCENE_NAME, SCENE_STEPS, SCENE_DT);
}

static int parse_long(const char *opt, const char *text, long *value)
{
    char *end;
    errno = 0;
    *value = strtol(text, &end, 10);
    if (errno || end == text || *end != '\0' || *value < 1) {
        fprintf(stderr, "touchdown: `%s` must be a positive integer, got '%s'.\n", opt, text);
        return 1;
    }
    return 0;
}

static int parse_double(const char *opt, const char *text, double *value)
{
    char *end;
    errno = 0;
    *value = strtod(text, &end);
    if (errno || end == text || *end != '\0' || !(*value > 0.0)) {
        fprintf(stderr, "touchdown: `%s` must be a positive number of seconds, got '%s'.\n",
                opt, text);
        return 1;
    }
    return 0;
}

static double seconds_between(const struct timespec *a, const struct timespec *b)
{
    return (double)(b->tv_sec - a->tv_sec) + 1e-9 * (double)(b->tv_nsec - a->tv_nsec);
}

int main(int argc, char *argv[])
{
    long steps = SCENE_STEPS, repeat = 1;
    double dt = SCENE_DT;
    const char *out_path = NULL;
    int i;

    for (i = 1; i < argc; ++i) {
        const char *opt = argv[i];
        if (strcmp(opt, "-h") == 0 || strcmp(opt, "--help") == 0) {
            usage(stdout);
            return 0;
        }
        if (i + 1 >= argc) {
            fprintf(stderr, "touchdown: option '%s' needs a value or is unknown.\n", opt);
            usage(stderr);
            return 2;
        }
        if (strcmp(opt, "-n") == 0) {
            if (parse_long(opt, argv[++i], &steps)) return 2;
        } else if (strcmp(opt, "-r") == 0) {
            if (parse_long(opt, argv[++i], &repeat)) return 2;
        } else if (strcmp(opt, "-d") == 0) {
            if (parse_double(opt, argv[++i], &dt)) return 2;
        } else if (strcmp(opt, "-o") == 0) {
            out_path = argv[++i];
        } else {
            fprintf(stderr, "touchdown: unknown option '%s'.\n", opt);
            usage(stderr);
            return 2;
        }
    }

    /* The generated Function must have the state size the scene data assumes. */
    const casadi_int *sp_x = touchdown_step_sparsity_in(0);
    if (sp_x[0] != SCENE_NX || sp_x[1] != 1) {
        fprintf(stderr, "touchdown: touchdown_step takes x of %lld x %lld, scene_data.h has %d; "
                        "regenerate both with the same scene.\n",
                (long long)sp_x[0], (long long)sp_x[1], SCENE_NX);
        return 1;
    }

    /* Work arrays of the generated code (casadi's calling convention). */
    casadi_int sz_arg, sz_res, sz_iw, sz_w;
    touchdown_step_work(&sz_arg, &sz_res, &sz_iw, &sz_w);
    const casadi_real **arg = malloc((size_t)(sz_arg > 0 ? sz_arg : 1) * sizeof *arg);
    casadi_real **res = malloc((size_t)(sz_res > 0 ? sz_res : 1) * sizeof *res);
    casadi_int *iw = malloc((size_t)(sz_iw > 0 ? sz_iw : 1) * sizeof *iw);
    casadi_real *w = malloc((size_t)(sz_w > 0 ? sz_w : 1) * sizeof *w);
    double *traj = malloc((size_t)(steps + 1) * SCENE_NX * sizeof *traj);
    double *y = malloc((size_t)touchdown_step_sparsity_out(1)[0] * sizeof *y);
    if (!arg || !res || !iw || !w || !traj || !y) {
        fprintf(stderr, "touchdown: out of memory for %ld steps.\n", steps);
        return 1;
    }

    touchdown_step_incref();
    int mem = touchdown_step_checkout();
    double best = -1.0;
    long r, k;
    for (r = 0; r < repeat; ++r) {
        struct timespec start, stop;
        memcpy(traj, scene_x0, SCENE_NX * sizeof *traj);
        arg[1] = scene_p;
        arg[2] = &dt;
        res[1] = y;
        clock_gettime(CLOCK_MONOTONIC, &start);
        for (k = 0; k < steps; ++k) {
            arg[0] = traj + k * SCENE_NX;
            res[0] = traj + (k + 1) * SCENE_NX;
            if (touchdown_step(arg, res, iw, w, mem)) {
                fprintf(stderr, "touchdown: touchdown_step failed at step %ld.\n", k);
                return 1;
            }
        }
        clock_gettime(CLOCK_MONOTONIC, &stop);
        double loop = seconds_between(&start, &stop);
        if (best < 0.0 || loop < best) best = loop;
    }
    touchdown_step_release(mem);
    touchdown_step_decref();

    FILE *out = stdout;
    if (out_path) {
        out = fopen(out_path, "w");
        if (!out) {
            fprintf(stderr, "touchdown: cannot write '%s': %s.\n", out_path, strerror(errno));
            return 1;
        }
    }
    fputs("t", out);
    for (i = 0; i < SCENE_NX; ++i) fprintf(out, ",%s", scene_state_names[i]);
    fputc('\n', out);
    for (k = 0; k <= steps; ++k) {
        fprintf(out, "%.17g", (double)k * dt);
        for (i = 0; i < SCENE_NX; ++i) fprintf(out, ",%.17g", traj[k * SCENE_NX + i]);
        fputc('\n', out);
    }
    if (out != stdout && fclose(out) != 0) {
        fprintf(stderr, "touchdown: error writing '%s'.\n", out_path);
        return 1;
    }

    fprintf(stderr, "touchdown: scene=%s steps=%ld dt=%.17g repeat=%ld loop_seconds=%.9g "
                    "per_step_us=%.6g\n",
            SCENE_NAME, steps, dt, repeat, best, 1e6 * best / (double)steps);
    free(arg);
    free(res);
    free(iw);
    free(w);
    free(traj);
    free(y);
    return 0;
}
