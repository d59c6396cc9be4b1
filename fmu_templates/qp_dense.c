/* The dense, strictly convex QP of qp_dense.h by the dual active-set method of Goldfarb and
 * Idnani (Math. Programming 27, 1983), in the product form of their paper: J = L^-T Q and the
 * upper-triangular R with J' N = [R; 0] for the normals N of the active constraints.
 *
 * The method starts at the unconstrained minimum x = -H^-1 g, which is optimal for the empty
 * set of constraints, and adds the most violated constraint (violation over its normal's
 * length) one at a time, dropping an active one whenever its multiplier would turn negative.
 * Every iterate is optimal for the constraints it holds, so the first one that violates none
 * is the solution; the dual objective rises at every addition, so no set repeats.
 * The method may add any violated constraint, not only the most violated: a caller that
 * expects an active set (the last sample's, shifted) names it, and those of its constraints
 * that are violated are added first, in its order, before the search over all constraints.
 * That saves the search (one pass over A) at each of them and the drops of constraints the
 * search would have picked wrongly; the solution is the same (to round-off: another order of
 * additions is another factorisation).
 * One iteration (an addition or a drop) costs O(n^2 + mn): one pass over A, two over J (d =
 * J' n_p, and the primal step z = J2 d2, which the reflection reuses), and a Householder
 * reflection (addition) or Givens rotations (drop) of J's and R's columns. The caller bounds the iterations; the iterates
 * before the last are not feasible, so a stopped solve is a failure, not an approximation.
 *
 * Constraint k of the 2(n + m) one-sided constraints n_k'x >= b_k: k / 2 is the variable
 * (k < 2n) or the row of A (k - 2n) / 2, k % 2 the side (0: >= lower; 1: <= upper, i.e.
 * -a'x >= -upper). Infinite bounds are no constraints.
 */
#include <math.h>
#include <string.h>

#include "qp_dense.h"

/* a constraint counts as violated beyond round-off when its slack is below
 * -QP_TOL * (1 + |bound|): the bound's own relative precision with four orders of margin for
 * the sums of up to a few hundred terms that form a'x */
#define QP_TOL 1e-10
/* a normal whose component outside the active normals' span is this small relative to its
 * length (in H^-1's metric) depends on them: the step is then dual only */
#define QP_DEPENDENT 1e-12

typedef struct {
    int n, m;
    const double *a, *lba, *uba, *lbx, *ubx;
} Problem;

static int side_of(int k) { return k & 1; }
static int item_of(int k) { return k >> 1; }

/* bound b_k of n_k'x >= b_k (infinite: no constraint) */
static double bound_of(const Problem *p, int k)
{
    const int i = item_of(k);
    if (i < p->n) {
        return side_of(k) ? -p->ubx[i] : p->lbx[i];
    }
    return side_of(k) ? -p->uba[i - p->n] : p->lba[i - p->n];
}

/* n_k'v */
static double normal_dot(const Problem *p, int k, const double *v)
{
    const int i = item_of(k);
    double s = 0.0;
    int c;
    if (i < p->n) {
        s = v[i];
    } else {
        for (c = 0; c < p->n; c++) {
            s += p->a[(i - p->n) + p->m * c] * v[c];
        }
    }
    return side_of(k) ? -s : s;
}

/* d = J' n_k (row into scratch first: A is column-major) */
static void project(const Problem *p, int k, const double *jm, double *d, double *scratch)
{
    const int n = p->n, i = item_of(k);
    const double sign = side_of(k) ? -1.0 : 1.0;
    int c, r;
    if (i < n) {
        for (c = 0; c < n; c++) {
            d[c] = sign * jm[i + n * c];
        }
        return;
    }
    for (r = 0; r < n; r++) {
        scratch[r] = sign * p->a[(i - n) + p->m * r];
    }
    for (c = 0; c < n; c++) {
        double s = 0.0;
        for (r = 0; r < n; r++) {
            s += jm[r + n * c] * scratch[r];
        }
        d[c] = s;
    }
}

/* the rotation (c, s) that maps (x, y) to (hypot(x, y), 0), applied to columns u and v of the
 * n-row column-major matrix w: u <- c u + s v, v <- -s u + c v */
static void rotate_columns(int n, double *w, int u, int v, double c, double s)
{
    int i;
    for (i = 0; i < n; i++) {
        const double x = w[i + n * u], y = w[i + n * v];
        w[i + n * u] = c * x + s * y;
        w[i + n * v] = -s * x + c * y;
    }
}

int qp_dense_factor(int n, const double *h, double *j, double *work)
{
    double *l = work; /* L, lower triangle, column-major */
    int r, c, k;
    for (c = 0; c < n; c++) {
        for (r = c; r < n; r++) {
            double s = h[r + n * c];
            for (k = 0; k < c; k++) {
                s -= l[r + n * k] * l[c + n * k];
            }
            if (r == c) {
                if (!(s > 0.0) || !isfinite(s)) {
                    return 1;
                }
                s = sqrt(s);
            } else {
                s /= l[c + n * c];
            }
            l[r + n * c] = s;
        }
    }
    /* column c of L^-1 by forward substitution, stored as row c of j = L^-T */
    memset(j, 0, sizeof(double) * (size_t)n * (size_t)n);
    for (c = 0; c < n; c++) {
        j[c + n * c] = 1.0 / l[c + n * c];
        for (r = c + 1; r < n; r++) {
            double s = 0.0;
            for (k = c; k < r; k++) {
                s += l[r + n * k] * j[c + n * k];
            }
            j[c + n * r] = -s / l[r + n * r];
        }
    }
    return 0;
}

/* the most violated constraint not active (by slack over normal length), or -1; its slack */
static int most_violated(const Problem *p, const double *x, double *ax, const double *norm,
                         const int *held, double *slack)
{
    const int n = p->n, m = p->m;
    double worst = 0.0;
    int best = -1, i, c, side;
    for (i = 0; i < m; i++) {
        ax[i] = 0.0;
    }
    for (c = 0; c < n; c++) {
        const double *col = p->a + (size_t)m * (size_t)c;
        for (i = 0; i < m; i++) {
            ax[i] += col[i] * x[c];
        }
    }
    for (i = 0; i < n + m; i++) {
        const double value = i < n ? x[i] : ax[i - n], length = i < n ? 1.0 : norm[i - n];
        if (held[i] || !(length > 0.0)) {
            continue;
        }
        for (side = 0; side < 2; side++) {
            const double b = bound_of(p, 2 * i + side);
            const double s = side ? -b - value : value - b; /* b is -upper on side 1 */
            if (isinf(b) || !(s < -QP_TOL * (1.0 + fabs(b)))) {
                continue;
            }
            if (s / length < worst) {
                worst = s / length;
                best = 2 * i + side;
                *slack = s;
            }
        }
    }
    return best;
}

/* The next of the caller's expected constraints first[*next ..] that is violated beyond
 * round-off and not active (*next moves past it), or -1; its slack. Indices out of range,
 * infinite bounds and rows of zero length are passed over. */
static int expected_violated(const Problem *p, const double *x, const double *norm,
                             const int *held, const int *first, int n_first, int *next,
                             double *slack)
{
    while (*next < n_first) {
        const int k = first[(*next)++], i = item_of(k);
        double b, s;
        if (k < 0 || i >= p->n + p->m || held[i] || (i >= p->n && !(norm[i - p->n] > 0.0))) {
            continue;
        }
        b = bound_of(p, k);
        s = normal_dot(p, k, x) - b;
        if (!isinf(b) && s < -QP_TOL * (1.0 + fabs(b))) {
            *slack = s;
            return k;
        }
    }
    return -1;
}

/* Drop the active constraint at position l: R loses column l and Givens rotations bring it
 * back to triangular form, turning J's columns alike; act and u (with the candidate's
 * multiplier at q) move up by one. */
static void drop(int n, int q, int l, double *jm, double *rr, int *act, double *u, int *held)
{
    int c, k;
    held[item_of(act[l])] = 0;
    for (c = l; c < q - 1; c++) {
        for (k = 0; k <= c + 1; k++) {
            rr[k + n * c] = rr[k + n * (c + 1)];
        }
    }
    for (c = l; c < q - 1; c++) {
        const double x = rr[c + n * c], y = rr[(c + 1) + n * c], h = hypot(x, y);
        double cs, sn;
        if (h == 0.0) {
            continue;
        }
        cs = x / h;
        sn = y / h;
        rr[c + n * c] = h;
        rr[(c + 1) + n * c] = 0.0;
        for (k = c + 1; k < q - 1; k++) {
            const double a = rr[c + n * k], b = rr[(c + 1) + n * k];
            rr[c + n * k] = cs * a + sn * b;
            rr[(c + 1) + n * k] = -sn * a + cs * b;
        }
        rotate_columns(n, jm, c, c + 1, cs, sn);
    }
    for (k = l; k < q; k++) {
        act[k] = act[k + 1];
        u[k] = u[k + 1];
    }
}

/* Add constraint p with d = J' n_p: one Householder reflection of J's columns q..n-1 maps
 * d's tail (positions q..n-1) to a multiple of position q; R gains column q = d[0..q].
 * z holds J2 d2, the iteration's primal step, on entry: the reflection's J2 v is that less
 * sigma J's column q (v is d's tail less sigma e_q), one column instead of a pass over J2;
 * z is overwritten. */
static void add(int n, int q, int p, double *d, double *jm, double *rr, int *act, int *held,
                double *z)
{
    double tail = 0.0, sigma, vv;
    int c, i, k;
    for (c = q; c < n; c++) {
        tail += d[c] * d[c];
    }
    sigma = d[q] >= 0.0 ? -sqrt(tail) : sqrt(tail);
    /* v = d[q..] - sigma e_q, kept in d; v'v = 2 (tail - sigma d[q]) */
    vv = 2.0 * (tail - sigma * d[q]);
    d[q] -= sigma;
    if (vv > 0.0) {
        const double *column_q = jm + (size_t)n * (size_t)q;
        for (i = 0; i < n; i++) { /* w = J2 v = z - sigma J e_q, kept in z */
            z[i] -= sigma * column_q[i];
        }
        for (c = q; c < n; c++) { /* J2 <- J2 - (2 / v'v) w v' */
            double *col = jm + (size_t)n * (size_t)c;
            const double f = 2.0 * d[c] / vv;
            for (i = 0; i < n; i++) {
                col[i] -= f * z[i];
            }
        }
    }
    d[q] = sigma;
    for (k = 0; k <= q; k++) {
        rr[k + n * q] = d[k];
    }
    act[q] = p;
    held[item_of(p)] = 1;
}

int qp_dense_solve(int n, int m, const double *j, const double *g, const double *a,
                   const double *lba, const double *uba, const double *lbx, const double *ubx,
                   const int *first, int n_first, int max_iter, double *x, int *iterations,
                   int *n_active, double *work, int *iwork)
{
    const Problem pr = {n, m, a, lba, uba, lbx, ubx};
    double *jm = work, *rr = jm + n * n, *d = rr + n * n, *z = d + n, *rv = z + n;
    double *u = rv + n, *ax = u + n + 1, *norm = ax + m;
    int *act = iwork, *held = act + n + 1;
    int q = 0, iter = 0, status = QP_DENSE_SOLVED, next = 0, i, c, k;

    memcpy(jm, j, sizeof(double) * (size_t)n * (size_t)n);
    memset(held, 0, sizeof(int) * (size_t)(n + m));
    for (i = 0; i < m; i++) {
        norm[i] = 0.0;
    }
    for (c = 0; c < n; c++) {
        const double *col = a + (size_t)m * (size_t)c;
        for (i = 0; i < m; i++) {
            norm[i] += col[i] * col[i];
        }
    }
    for (i = 0; i < m; i++) {
        norm[i] = sqrt(norm[i]);
    }
    /* x = -H^-1 g = -J J' g */
    for (c = 0; c < n; c++) {
        double s = 0.0;
        for (i = 0; i <= c; i++) {
            s += jm[i + n * c] * g[i];
        }
        d[c] = s;
    }
    for (i = 0; i < n; i++) {
        x[i] = 0.0;
    }
    for (c = 0; c < n; c++) {
        for (i = 0; i <= c; i++) {
            x[i] -= jm[i + n * c] * d[c];
        }
    }
    for (;;) {
        double slack = 0.0;
        int p = expected_violated(&pr, x, norm, held, first, n_first, &next, &slack);
        if (p < 0) {
            p = most_violated(&pr, x, ax, norm, held, &slack);
        }
        if (p < 0) {
            break;
        }
        u[q] = 0.0;
        for (;;) { /* steps towards satisfying p, dropping what blocks them */
            double t1 = INFINITY, t2 = INFINITY, along = 0.0, t;
            int l = -1;
            if (iter >= max_iter) {
                status = QP_DENSE_MAX_ITER;
                goto done;
            }
            iter++;
            project(&pr, p, jm, d, z);
            for (i = 0; i < n; i++) {
                z[i] = 0.0;
            }
            for (c = q; c < n; c++) { /* z = J2 d2: the primal step */
                const double *col = jm + (size_t)n * (size_t)c;
                for (i = 0; i < n; i++) {
                    z[i] += col[i] * d[c];
                }
            }
            for (k = q - 1; k >= 0; k--) { /* rv = R^-1 d1: the active multipliers' step */
                double s = d[k];
                for (c = k + 1; c < q; c++) {
                    s -= rr[k + n * c] * rv[c];
                }
                rv[k] = s / rr[k + n * k];
            }
            for (k = 0; k < q; k++) { /* the partial step: an active multiplier reaches 0 */
                if (rv[k] > 0.0 && u[k] / rv[k] < t1) {
                    t1 = u[k] / rv[k];
                    l = k;
                }
            }
            {
                double tail = 0.0, whole = 0.0;
                for (c = 0; c < n; c++) {
                    whole += d[c] * d[c];
                    tail += c >= q ? d[c] * d[c] : 0.0;
                }
                if (tail > QP_DEPENDENT * whole) { /* the full step: p becomes active */
                    along = normal_dot(&pr, p, z);
                    t2 = -slack / along;
                }
            }
            if (!isfinite(t1) && !isfinite(t2)) {
                status = QP_DENSE_INFEASIBLE;
                goto done;
            }
            t = t1 < t2 ? t1 : t2;
            for (k = 0; k < q; k++) {
                u[k] -= t * rv[k];
            }
            u[q] += t;
            if (isfinite(t2)) {
                for (i = 0; i < n; i++) {
                    x[i] += t * z[i];
                }
                slack += t * along;
            }
            if (isfinite(t2) && t2 <= t1) {
                add(n, q, p, d, jm, rr, act, held, z);
                q++;
                break;
            }
            drop(n, q, l, jm, rr, act, u, held);
            q--;
        }
        for (i = 0; i < n; i++) {
            if (!isfinite(x[i])) {
                status = QP_DENSE_NOT_FINITE;
                goto done;
            }
        }
    }
done:
    *iterations = iter;
    *n_active = q;
    return status;
}
