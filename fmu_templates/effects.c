/* Effect blocks: the block pipeline of gatetwin.plant.simulate.PlantSimulator (see effects.h) on
 * the blocks' arithmetic generated from gatetwin/plant/blocks.py (blocks.c).
 *
 * A block the model does not carry (GT_HAS_<BLOCK> 0 in model_config.h) compiles to the
 * identity or to nothing; its parameters then have no value reference.
 */
#include <math.h>

#include "blocks.h"
#include "plant.h"

#define PARAMETER(m, vr) ((m)->real[vr])

/* --- parameter checks: the limits table is generated from gatetwin.plant.effects ------------ */

typedef struct {
    int vr;
    double minimum;
    double maximum;
    int minimum_exclusive;
} EffectLimit;

#define GT_EFFECT_LIMIT_ENTRY(vr, lo, hi, exclusive) {vr, lo, hi, exclusive},
static const EffectLimit effect_limits[] = {GT_EFFECT_LIMITS(GT_EFFECT_LIMIT_ENTRY){-1, 0.0, 0.0, 0}};
#undef GT_EFFECT_LIMIT_ENTRY

PlantStatus effects_check_parameters(const ModelData *m, PlantMessage *msg)
{
    const EffectLimit *limit;
    for (limit = effect_limits; limit->vr >= 0; limit++) {
        const double value = m->real[limit->vr];
        const char *name = plant_variables[limit->vr].name;
        if (limit->minimum_exclusive && !(value > limit->minimum)) {
            plant_message(msg, "%s = %.17g must be > %g", name, value, limit->minimum);
            return PLANT_ERROR;
        }
        if (!limit->minimum_exclusive && !(value >= limit->minimum)) {
            plant_message(msg, "%s = %.17g must be >= %g", name, value, limit->minimum);
            return PLANT_ERROR;
        }
        if (!(value <= limit->maximum)) {
            plant_message(msg, "%s = %.17g must be <= %g", name, value, limit->maximum);
            return PLANT_ERROR;
        }
    }
    return PLANT_OK;
}

/* The blocks' arithmetic is blocks.c, generated from gatetwin/plant/blocks.py (gt_ prefix). */

/* --- input blocks ---------------------------------------------------------------------------- */

double effects_input(const ModelData *m, double gate_mm)
{
    const double v = gate_mm - m->real[VR_OPENING_REF_MM];
#if GT_HAS_NONLINEARITY
    return gt_gain_map(v, PARAMETER(m, VR_FX_NONLINEARITY_GAIN_SLOPE_PER_MM));
#else
    return v;
#endif
}

void effects_actuate(const ModelData *m, EffectState *fx, double command_mm, double duration_s)
{
    (void)m;
    (void)duration_s;
#if GT_HAS_RATE_LIMIT
    fx->actuator_mm = gt_move_toward(fx->actuator_mm, command_mm,
                                  PARAMETER(m, VR_FX_RATE_LIMIT_RATE_MM_PER_S) * duration_s);
#else
    fx->actuator_mm = command_mm;
#endif
#if GT_HAS_BACKLASH
    fx->gate_mm = gt_play(fx->gate_mm, fx->actuator_mm, PARAMETER(m, VR_FX_BACKLASH_DEADBAND_MM));
#else
    fx->gate_mm = fx->actuator_mm;
#endif
}

void effects_fopdt_parameters(const ModelData *m, double flow_m3h, double *gain,
                              double *time_constant_s)
{
#if GT_HAS_FLOW_GAIN
    const double flow_ref = PARAMETER(m, VR_FX_FLOW_GAIN_FLOW_REF_M3H);
    *gain = gt_flow_scaled(*gain, PARAMETER(m, VR_FX_FLOW_GAIN_GAIN_SLOPE_PER_M3H), flow_m3h,
                           flow_ref);
    *time_constant_s = gt_flow_scaled(*time_constant_s,
                                      PARAMETER(m, VR_FX_FLOW_GAIN_TIME_CONSTANT_SLOPE_PER_M3H),
                                      flow_m3h, flow_ref);
#else
    (void)m;
    (void)flow_m3h;
    (void)gain;
    (void)time_constant_s;
#endif
}

/* --- output blocks --------------------------------------------------------------------------- */

void effects_initialize(ModelData *m, double opening_mm, double flow_m3h, double level_mm)
{
    EffectState *fx = &m->fx;
    fx->actuator_mm = opening_mm;
    fx->gate_mm = opening_mm;
    fx->held_gate_mm = opening_mm;
    fx->grid_origin_s = m->time_s;
    fx->seiche_x1 = 0.0;
    fx->seiche_x2 = 0.0;
    fx->inflow_mm = 0.0;
    fx->drift_mm = 0.0;
#if GT_HAS_SEICHE
    fx->seiche_x1 = gt_seiche_equilibrium(opening_mm - m->real[VR_OPENING_REF_MM],
                                          PARAMETER(m, VR_FX_SEICHE_PERIOD_S),
                                          PARAMETER(m, VR_FX_SEICHE_DECAY_TIME_S));
#endif
#if GT_HAS_INFLOW
    fx->inflow_mm = PARAMETER(m, VR_FX_INFLOW_GAIN_MM_PER_M3H) *
                    (flow_m3h - PARAMETER(m, VR_FX_INFLOW_FLOW_REF_M3H));
#else
    (void)flow_m3h;
#endif
    fx->sensed_mm = level_mm;
}

void effects_seiche_piece(ModelData *m, double duration_s, double gate_mm)
{
#if GT_HAS_SEICHE
    gt_seiche_advance(m->fx.seiche_x1, m->fx.seiche_x2, gate_mm - m->real[VR_OPENING_REF_MM],
                      duration_s, PARAMETER(m, VR_FX_SEICHE_PERIOD_S),
                      PARAMETER(m, VR_FX_SEICHE_DECAY_TIME_S), &m->fx.seiche_x1,
                      &m->fx.seiche_x2);
#else
    (void)m;
    (void)duration_s;
    (void)gate_mm;
#endif
}

void effects_lag_interval(ModelData *m, double level_target_mm, double level_excess_mm,
                          double duration_s, double level_time_constant_s)
{
#if GT_HAS_LAG
    m->fx.sensed_mm = gt_lag_interval(m->fx.sensed_mm, level_target_mm, level_excess_mm,
                                      duration_s, level_time_constant_s,
                                      PARAMETER(m, VR_FX_LAG_TIME_CONSTANT_S));
#else
    (void)m;
    (void)level_target_mm;
    (void)level_excess_mm;
    (void)duration_s;
    (void)level_time_constant_s;
#endif
}

void effects_lag_sample(ModelData *m, double level_mm, double duration_s)
{
#if GT_HAS_LAG
    m->fx.sensed_mm = gt_first_order(m->fx.sensed_mm, level_mm, duration_s,
                                  PARAMETER(m, VR_FX_LAG_TIME_CONSTANT_S));
#else
    (void)m;
    (void)level_mm;
    (void)duration_s;
#endif
}

void effects_step_end(ModelData *m, double step_s, double flow_m3h)
{
#if GT_HAS_INFLOW
    {
        const double target = PARAMETER(m, VR_FX_INFLOW_GAIN_MM_PER_M3H) *
                              (flow_m3h - PARAMETER(m, VR_FX_INFLOW_FLOW_REF_M3H));
        m->fx.inflow_mm = gt_first_order(m->fx.inflow_mm, target, step_s,
                                      PARAMETER(m, VR_FX_INFLOW_TIME_CONSTANT_S));
    }
#else
    (void)flow_m3h;
#endif
#if GT_HAS_DRIFT
    m->fx.drift_mm += PARAMETER(m, VR_FX_DRIFT_RATE_MM_PER_S) * step_s;
#else
    (void)m;
    (void)step_s;
#endif
}

double effects_output(const ModelData *m, double level_mm)
{
    double y = level_mm;
#if GT_HAS_LAG
    y = m->fx.sensed_mm;
#endif
#if GT_HAS_SEICHE
    y += gt_seiche_output(m->fx.seiche_x2, PARAMETER(m, VR_FX_SEICHE_PERIOD_S),
                          PARAMETER(m, VR_FX_SEICHE_AMPLITUDE_MM_PER_MM));
#endif
#if GT_HAS_INFLOW
    y += m->fx.inflow_mm;
#endif
#if GT_HAS_DRIFT
    y += m->fx.drift_mm;
#endif
    (void)m;
    return y;
}

double effects_output_at_rest(const ModelData *m, double level_mm, double flow_m3h)
{
    double y = level_mm;
#if GT_HAS_INFLOW
    y += PARAMETER(m, VR_FX_INFLOW_GAIN_MM_PER_M3H) *
         (flow_m3h - PARAMETER(m, VR_FX_INFLOW_FLOW_REF_M3H));
#else
    (void)m;
    (void)flow_m3h;
#endif
    return y;
}
