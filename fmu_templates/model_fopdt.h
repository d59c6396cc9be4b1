/* State of the scheduled FOPDT dynamics and what a step derives from its inputs alone
 * (equations in model_fopdt.c). */
#ifndef GATETWIN_MODEL_FOPDT_H
#define GATETWIN_MODEL_FOPDT_H

/* GT_HISTORY_CAPACITY (input change points kept for the dead time) comes from model_config.h,
 * generated from gatetwin.plant.simulate.DELAY_HISTORY_CAPACITY. */

/* Decays a step cache keeps: with a fixed communication step h and inputs that change at
 * communication points, a piece lasts h, or the two parts of a step an input arrives in
 * after the dead time (L mod h and h minus it), so three slots hold every piece's decay. */
#define GT_DECAY_SLOTS 3

typedef struct {
    double x;                                /* deviation from level_ref, mm */
    double change_t[GT_HISTORY_CAPACITY];    /* time of each input change, s (ring buffer) */
    double change_u[GT_HISTORY_CAPACITY];    /* input deviation in force from then on, mm */
    double tail_m; /* an envelope's pool below the gate: its depth, m (0: a free gate) */
    int head;                                /* ring position of the oldest change */
    int count;                               /* changes held, >= 1 once initialised */
    double max_dead_time_s;                  /* history horizon, fixed at initialisation */
} DynamicsState;

/* What a step derives from its discharge and the parameters alone (ModelData.cache, see
 * plant_data.h): the scheduled K, T, L and level_ref, the first-order decays of the last
 * pieces (pieces repeat their duration and T), and an envelope's steady point at the last
 * arrived input it needed. */
typedef struct {
    double gain;         /* K, flow-dependent gain applied, mm/mm */
    double tau_s;        /* T, flow-dependent gain applied, s */
    double delay_s;      /* L, s */
    double level_ref_mm; /* level_ref, mm */
    int decay_filled;                        /* slots below in use, 0 .. GT_DECAY_SLOTS */
    int decay_next;                          /* the slot the next new decay replaces */
    double decay_duration_s[GT_DECAY_SLOTS]; /* the piece's duration a slot is for, s */
    double decay_tau_s[GT_DECAY_SLOTS];      /* the time constant it is for, s */
    double decay[GT_DECAY_SLOTS];            /* exp(-duration / T): the deviation left */
#if GT_ENVELOPE
    int point_valid;         /* 1: the steady point below holds for point_u_mm */
    double point_u_mm;       /* the arrived input deviation it is at, mm */
    double point_level_mm;   /* the gate law's steady level there, mm */
    double point_tau_s;      /* the storage's time constant there (the tangent), s */
    double point_depth_m;    /* the steady depth at the gate there, m */
#endif
} DynamicsCache;

#endif
