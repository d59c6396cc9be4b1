/* State of the physical dynamics: pool storage drained by the gate law, behind the actuator.
 * The arithmetic is generated into physical_kernel.c from gatetwin.plant.physical_kernel. */
#ifndef GATETWIN_MODEL_PHYSICAL_H
#define GATETWIN_MODEL_PHYSICAL_H

typedef struct {
    double x;       /* level at the gauge, mm (level_ref_mm is added by plant.c) */
    double depth_m; /* depth at the gate, m */
    double tail_m;  /* depth of the pool below the gate, m (0 without one) */
    double gate_mm; /* gate position, mm */
} DynamicsState;

/* The physical family derives nothing from the discharge alone (the steady depth is only its
 * initial state): the step cache (plant_data.h) holds the knot position only. */
typedef struct {
    int none; /* C wants a member: always 0 */
} DynamicsCache;

#endif
