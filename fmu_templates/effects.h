/* Effect blocks around the dynamics (semantics: gatetwin/plant/effects.py):
 *
 *   command --rate limit--> actuator --backlash--> gate --nonlinearity--> u --> dynamics
 *   level = level_ref(Q) + x --sensor lag--> + seiche(gate) + inflow(Q) + drift --> output
 *
 * Which blocks a model carries, and the value references of their parameters, come from the
 * generated model_config.h (GT_HAS_<BLOCK>, VR_FX_<BLOCK>_<PARAMETER>, GT_EFFECT_LIMITS).
 * Their state lives in ModelData (plant.h), so FMU states (get/set/serialize) carry it.
 * The arithmetic mirrors gatetwin/plant/blocks.py operation by operation; the pipeline that
 * calls it mirrors gatetwin.plant.simulate.PlantSimulator.
 */
#ifndef GATETWIN_EFFECTS_H
#define GATETWIN_EFFECTS_H

/* State of every block (fields of absent blocks stay 0). */
typedef struct {
    double actuator_mm;   /* actuator position a (rate limit), mm */
    double gate_mm;       /* gate position g (after the backlash), mm */
    double held_gate_mm;  /* gate position the FOPDT sees, sampled on the actuator grid, mm */
    double grid_origin_s; /* origin of the actuator grid: the initialisation time, s */
    double seiche_x1;     /* seiche oscillator states */
    double seiche_x2;
    double inflow_mm;     /* inflow term, mm */
    double drift_mm;      /* accumulated drift, mm */
    double sensed_mm;     /* sensor-lag output, mm */
} EffectState;

#endif
