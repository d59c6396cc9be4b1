/* State of the scheduled ARX(na, nb, nk) dynamics and what a step derives from its inputs
 * alone (equations in model_arx.c). */
#ifndef GATETWIN_MODEL_ARX_H
#define GATETWIN_MODEL_ARX_H

#define GT_ARX_U_LAGS (GT_NK + GT_NB - 1)

typedef struct {
    double x;                     /* deviation from level_ref, mm */
    double x_hist[GT_NA];         /* x_hist[i] = x(k - i) */
    double u_hist[GT_ARX_U_LAGS]; /* u_hist[m] = u(k - m), u(k) the input held over the sample */
} DynamicsState;

/* What a step derives from its discharge and the parameters alone (ModelData.cache, see
 * plant_data.h): the scheduled coefficients and level_ref, and an envelope ARX's input and
 * coefficients at the last input it needed. */
typedef struct {
    double a[GT_NA];     /* a_(i+1) at the discharge */
    double b[GT_NB];     /* b_(j+1) at the discharge */
    double level_ref_mm; /* level_ref, mm */
#if GT_ENVELOPE
    double time_constant_ref_s; /* the pool's time constant where a1 was identified, s */
    int point_valid;            /* 1: the three below hold for point_u_mm */
    double point_u_mm;          /* the input deviation they are at, mm */
    double point_level_mm;      /* the gate law's steady level there: the ARX's input, mm */
    double point_a1;            /* a1 scaled by the pool's time constant there */
    double point_b[GT_NB];      /* the b rescaled to unit gain at point_a1 */
#endif
} DynamicsCache;

#endif
