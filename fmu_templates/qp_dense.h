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

/* Solve the QP from the factor j of H; infinite bounds are no constraints. x receives the
 * solution; iterations the additions and drops taken (at most max_iter); n_active the
 * constraints active at the end. Returns a QP_DENSE_* status. */
int qp_dense_solve(int n, int m, const double *j, const double *g, const double *a,
                   const double *lba, const double *uba, const double *lbx, const double *ubx,
                   int max_iter, double *x, int *iterations, int *n_active, double *work,
                   int *iwork);

#endif
