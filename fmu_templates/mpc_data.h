/* ModelData of the MPC controller FMU (the component of component.h): every Real variable,
 * the observer's estimate, the QP of the last sample and the generated code's work arrays.
 * Fixed size and pointer-free (copied and serialised as bytes by the FMU-state functions); the
 * sizes come from the generated model_config.h.
 */
#ifndef GATETWIN_MPC_DATA_H
#define GATETWIN_MPC_DATA_H

#include "model_config.h"
#include "mpc_generated.h" /* casadi_int, casadi_real and the generated functions */
#include "qp_dense.h"

typedef struct {
    double time_s;          /* time of the state, s */
    double real[GT_N_REAL]; /* every Real variable, indexed by value reference */
    int initialized;        /* plant_initialize succeeded */
    int parameters_changed; /* parameters were set since they were last checked */
    int have_matrices;      /* factor and a hold the QP's matrices at flow_matrices_m3h */
    /* the observer: state, input disturbance (mm of opening), prior covariance of [z, d] */
    double z[GT_GEN_NZ];
    double d;
    double p[GT_GEN_NP];
    double opening_mm;        /* opening held since the last sample (the rate limit's anchor) */
    double flow_model_m3h;    /* discharge of the observer's model (the last prediction's) */
    double flow_matrices_m3h; /* discharge factor and a were formed at */
    int warned_setpoint;         /* the set-point outside the band was warned about ... */
    double warned_setpoint_mm;   /* ... and was this */
    /* the QP's matrices at that discharge (column-major, dense): the Hessian's factor
     * L^-T (qp_dense_factor) and the constraint rows */
    double factor[GT_MPC_NV * GT_MPC_NV];
    double a[GT_MPC_NC * GT_MPC_NV];
    /* scratch of one sample: the QP's vectors, the solver's and the generated code's work */
    double g[GT_MPC_NV], lba[GT_MPC_NC], uba[GT_MPC_NC], lbx[GT_MPC_NV], ubx[GT_MPC_NV];
    /* the last sample's active constraints, shifted a sample on: the next QP's first guess */
    int expected[GT_MPC_NV];
    int n_expected;
    double qp_work[QP_DENSE_WORK(GT_MPC_NV, GT_MPC_NC)];
    int qp_iwork[QP_DENSE_IWORK(GT_MPC_NV, GT_MPC_NC)];
    casadi_int iw[GT_GEN_SZ_IW];
    casadi_real w[GT_GEN_SZ_W];
} ModelData;

#endif
