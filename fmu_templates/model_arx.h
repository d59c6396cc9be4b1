/* State of the scheduled ARX(na, nb, nk) dynamics (equations in model_arx.c). */
#ifndef GATETWIN_MODEL_ARX_H
#define GATETWIN_MODEL_ARX_H

#define GT_ARX_U_LAGS (GT_NK + GT_NB - 1)

typedef struct {
    double x;                     /* deviation from level_ref, mm */
    double x_hist[GT_NA];         /* x_hist[i] = x(k - i) */
    double u_hist[GT_ARX_U_LAGS]; /* u_hist[m] = u(k - m), u(k) the input held over the sample */
} DynamicsState;

#endif
