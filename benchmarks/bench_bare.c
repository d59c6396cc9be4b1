/* The bare reference of bench_fmu.py: the FOPDT step with nothing around it.
 *
 * usage: bench_bare K T L LEVEL_REF STEP_S N
 *
 * T dx/dt = K u(t - L) - x, exact for piecewise-constant input, the dead time served from a
 * history of input change points (the arithmetic the C FMU performs, model_fopdt.c), with the
 * parameters fixed at the held discharge: no schedule, no checks, no FMI, no effect blocks.
 * The calls go through function pointers the compiler cannot see through, so each step
 * pays three calls like the FMU's setReal + doStep + getReal. Prints one line like
 * bench_host: set_step_get_ns.
 */
#define _POSIX_C_SOURCE 199309L
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#define CAPACITY 64

typedef struct {
    double gain, tau_s, delay_s, level_ref_mm;
    double x, t, u;
    double change_t[CAPACITY], change_u[CAPACITY];
    int head, count;
} Bare;

static double now_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec * 1e9 + ts.tv_nsec;
}

static int slot(const Bare *b, int j)
{
    return (b->head + j) % CAPACITY;
}

static void bare_set(Bare *b, double u)
{
    b->u = u;
}

static void bare_step(Bare *b, double h)
{
    const double t_end = b->t + h;
    double t = b->t;
    int j;
    if (b->u != b->change_u[slot(b, b->count - 1)]) { /* a new change point */
        b->change_t[slot(b, b->count)] = b->t;
        b->change_u[slot(b, b->count)] = b->u;
        b->count++;
    }
    while (b->count > 1 && b->change_t[slot(b, 1)] + b->delay_s <= b->t) { /* arrived */
        b->head = slot(b, 1);
        b->count--;
    }
    for (j = 0; j < b->count && t < t_end; j++) { /* pieces of constant delayed input */
        const double next = j + 1 < b->count ? b->change_t[slot(b, j + 1)] + b->delay_s : t_end;
        const double end = next < t_end ? next : t_end;
        const double a = exp(-(end - t) / b->tau_s);
        if (end > t) {
            b->x = a * b->x + (1.0 - a) * (b->gain * b->change_u[slot(b, j)]);
            t = end;
        }
    }
    b->t = t_end;
}

static double bare_get(const Bare *b)
{
    return b->level_ref_mm + b->x;
}

int main(int argc, char **argv)
{
    void (*volatile set)(Bare *, double) = bare_set;
    void (*volatile step)(Bare *, double) = bare_step;
    double (*volatile get)(const Bare *) = bare_get;
    Bare *b;
    double step_s, start, level = 0.0;
    long n, k;
    if (argc < 7) {
        fprintf(stderr, "usage: %s K T L LEVEL_REF STEP_S N\n", argv[0]);
        return 2;
    }
    b = calloc(1, sizeof *b);
    if (!b) {
        return 1;
    }
    b->gain = atof(argv[1]);
    b->tau_s = atof(argv[2]);
    b->delay_s = atof(argv[3]);
    b->level_ref_mm = atof(argv[4]);
    step_s = atof(argv[5]);
    n = atol(argv[6]);
    b->count = 1; /* at rest at u = 0 (deviation from the reference opening) */
    for (k = 0; k < n / 10 + 1; k++) { /* warm up, as bench_host does */
        set(b, 4.0);
        step(b, step_s);
    }
    start = now_ns();
    for (k = 0; k < n; k++) {
        set(b, (k / 7) % 2 ? -2.0 : 3.0); /* bench_host's 18/23 mm around the 20 mm reference */
        step(b, step_s);
        level = get(b);
    }
    printf("set_step_get_ns %.2f\n", (now_ns() - start) / n);
    printf("level %.6f\n", level);
    free(b);
    return 0;
}
