/* State of the scheduled FOPDT dynamics (equations in model_fopdt.c). */
#ifndef GATETWIN_MODEL_FOPDT_H
#define GATETWIN_MODEL_FOPDT_H

/* GT_HISTORY_CAPACITY (input change points kept for the dead time) comes from model_config.h,
 * generated from gatetwin.plant.simulate.DELAY_HISTORY_CAPACITY. */

typedef struct {
    double x;                                /* deviation from level_ref, mm */
    double change_t[GT_HISTORY_CAPACITY];    /* time of each input change, s (ring buffer) */
    double change_u[GT_HISTORY_CAPACITY];    /* input deviation in force from then on, mm */
    int head;                                /* ring position of the oldest change */
    int count;                               /* changes held, >= 1 once initialised */
    double max_dead_time_s;                  /* history horizon, fixed at initialisation */
} DynamicsState;

#endif
