/* State of the scheduled FOPDT dynamics and what a step derives from its inputs alone
 * (equations in model_fopdt.c). */
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

/* What a step derives from its discharge and the parameters alone (ModelData.cache, see
 * plant_data.h): the scheduled K, T, L and level_ref, the first-order decay of the last piece
 * (a step's pieces repeat their duration and T), and an envelope's steady point at the last
 * arrived input it needed. */
typedef struct {
    double gain;         /* K, flow-dependent gain applied, mm/mm */
    double tau_s;        /* T, flow-dependent gain applied, s */
    double delay_s;      /* L, s */
    double level_ref_mm; /* level_ref, mm */
    int decay_valid;         /* 1: decay below holds for decay_duration_s and decay_tau_s */
    double decay_duration_s; /* the piece's duration it is for, s */
    double decay_tau_s;      /* the time constant it is for, s */
    double decay;            /* exp(-duration / T): the fraction of the deviation left */
#if GT_ENVELOPE
    int point_valid;         /* 1: the steady point below holds for point_u_mm */
    double point_u_mm;       /* the arrived input deviation it is at, mm */
    double point_level_mm;   /* the gate law's steady level there, mm */
    double point_tau_s;      /* the storage's time constant there, s */
#endif
} DynamicsCache;

#endif
