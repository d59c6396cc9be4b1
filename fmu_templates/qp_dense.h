/* A small dense, strictly convex QP solver for the MPC controller FMU (qp_dense.c):
 *
 *     min ½ x'Hx + g'x   s.t.   lbx <= x <= ubx,   lba <= A x <= uba
 *
 * with H (n × n) symmetric positive definite and A (m × n), both column-major. Fixed-size
 * callers size their arrays with the macros below; the solver allocates nothing.
 */
#ifndef GATETWIN_QP_DENSE_H
#define GATETWIN_QP_DENSE_H

/* doubles and ints of qp_dense_solve's workspace for n variables and m rows */
#define QP_DENSE_WORK(n, m) (2 * (n) * (n) + 5 * (n) + 2 + 2 * (m))
#define QP_DENSE_IWORK(n, m) (2 * (n) + (m) + 1)

enum {
    QP_DENSE_SOLVED = 0,     /* optimal: no constraint violated beyond round-off */
    QP_DENSE_MAX_ITER = 1,   /* stopped at max_iter: x is not feasible */
    QP_DENSE_INFEASIBLE = 2, /* the constraints admit no point */
    QP_DENSE_NOT_FINITE = 3  /* a non-finite number in the data or the iterates */
};

/* The factor the solver starts from: j = L^-T with L L' = h (n × n, column-major; upper
 * triangular). work holds n × n doubles. Returns 0, or 1 when h is not positive definite
 * or not finite. */
int qp_dense_factor(int n, const double *h, double *j, double *work);

/* Constraint k of the QP (the numbering of first and of the active set): k / 2 is the
 * variable (k / 2 < n) or the row of A (k / 2 - n), k % 2 the side (0 the lower bound, 1 the
 * upper). */

/* Solve the QP from the factor j of H; infinite bounds are no constraints. first[0 ..
 * n_first - 1] (first may be NULL when n_first is 0) are constraints expected to be active,
 * tried before the others (any index is safe: those that are not constraints are passed
 * over). x receives the solution; iterations the additions and drops taken (at most
 * max_iter); n_active the constraints active at the end, and iwork[0 .. n_active - 1] those
 * constraints. Returns a QP_DENSE_* status. */
int qp_dense_solve(int n, int m, const double *j, const double *g, const double *a,
                   const double *lba, const double *uba, const double *lbx, const double *ubx,
                   const int *first, int n_first, int max_iter, double *x, int *iterations,
                   int *n_active, double *work, int *iwork);

#endif
