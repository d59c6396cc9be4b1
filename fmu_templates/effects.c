/* Effect blocks: the arithmetic of gatetwin/plant/blocks.py and the block pipeline of
 * gatetwin.plant.simulate.PlantSimulator, operation by operation (see effects.h).
 *
 * A block the model does not carry (GT_HAS_<BLOCK> 0 in model_config.h) compiles to the
 * identity or to nothing; its parameters then have no value reference.
 */
#include <math.h>

#include "plant.h"

#define GT_PI 3.141592653589793 /* the double nearest pi, as Python's math.pi */
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

/* A restored state: every block's value finite, the actuator grid's origin not after the
 * state's time (the grid is indexed from it). */
PlantStatus effects_check_state(const ModelData *m, PlantMessage *msg)
{
    const EffectState *fx = &m->fx;
    const double values[] = {fx->actuator_mm, fx->gate_mm,   fx->held_gate_mm,
                             fx->grid_origin_s, fx->seiche_x1, fx->seiche_x2,
                             fx->inflow_mm,   fx->drift_mm,  fx->sensed_mm};
    size_t i;
    for (i = 0; i < sizeof values / sizeof values[0]; i++) {
        if (!isfinite(values[i])) {
            plant_message(msg, "effect-block state value %d is not finite", (int)i);
            return PLANT_ERROR;
        }
    }
    if (!(fabs(fx->grid_origin_s) <= GT_MAX_TIME_S &&
          (!m->initialized || fx->grid_origin_s <= m->time_s))) {
        plant_message(msg, "actuator grid origin %g s lies after the state's time %g s",
                      fx->grid_origin_s, m->time_s);
        return PLANT_ERROR;
    }
    return PLANT_OK;
}

/* --- kernels (gatetwin/plant/blocks.py) ------------------------------------------------------ */

#if GT_HAS_RATE_LIMIT
static double move_toward(double position_mm, double command_mm, double max_travel_mm)
{
    const double diff = command_mm - position_mm;
    if (diff > max_travel_mm) {
        return position_mm + max_travel_mm;
    }
    if (diff < -max_travel_mm) {
        return position_mm - max_travel_mm;
    }
    return command_mm;
}
#endif

#if GT_HAS_BACKLASH
static double play(double gate_mm, double actuator_mm, double deadband_mm)
{
    const double half = 0.5 * deadband_mm;
    if (actuator_mm - gate_mm > half) {
        return actuator_mm - half;
    }
    if (actuator_mm - gate_mm < -half) {
        return actuator_mm + half;
    }
    return gate_mm;
}
#endif

#if GT_HAS_LAG || GT_HAS_INFLOW
static double first_order(double state, double target, double duration_s, double tau_s)
{
    return target + (state - target) * exp(-duration_s / tau_s);
}
#endif

double grid_index_at_or_after(double time_s, double origin_s, double step_s)
{
    double k = ceil((time_s - origin_s) / step_s);
    if (k < 0.0) {
        k = 0.0;
    }
    while (k > 0.0 && origin_s + (k - 1.0) * step_s >= time_s) {
        k -= 1.0;
    }
    while (origin_s + k * step_s < time_s) {
        k += 1.0;
    }
    return k;
}

/* --- input blocks ---------------------------------------------------------------------------- */

double effects_input(const ModelData *m, double gate_mm)
{
    const double v = gate_mm - m->real[VR_OPENING_REF_MM];
#if GT_HAS_NONLINEARITY
    const double slope = PARAMETER(m, VR_FX_NONLINEARITY_GAIN_SLOPE_PER_MM);
    if (slope == 0.0) {
        return v;
    }
    return expm1(slope * v) / slope;
#else
    return v;
#endif
}

void effects_actuate(const ModelData *m, EffectState *fx, double command_mm, double duration_s)
{
    (void)m;
    (void)duration_s;
#if GT_HAS_RATE_LIMIT
    fx->actuator_mm = move_toward(fx->actuator_mm, command_mm,
                                  PARAMETER(m, VR_FX_RATE_LIMIT_RATE_MM_PER_S) * duration_s);
#else
    fx->actuator_mm = command_mm;
#endif
#if GT_HAS_BACKLASH
    fx->gate_mm = play(fx->gate_mm, fx->actuator_mm, PARAMETER(m, VR_FX_BACKLASH_DEADBAND_MM));
#else
    fx->gate_mm = fx->actuator_mm;
#endif
}

void effects_fopdt_parameters(const ModelData *m, double flow_m3h, double *gain,
                              double *time_constant_s)
{
#if GT_HAS_FLOW_GAIN
    const double dq = flow_m3h - PARAMETER(m, VR_FX_FLOW_GAIN_FLOW_REF_M3H);
    *gain = *gain * exp(PARAMETER(m, VR_FX_FLOW_GAIN_GAIN_SLOPE_PER_M3H) * dq);
    *time_constant_s =
        *time_constant_s * exp(PARAMETER(m, VR_FX_FLOW_GAIN_TIME_CONSTANT_SLOPE_PER_M3H) * dq);
#else
    (void)m;
    (void)flow_m3h;
    (void)gain;
    (void)time_constant_s;
#endif
}

/* --- output blocks --------------------------------------------------------------------------- */

#if GT_HAS_SEICHE
static void seiche_advance(EffectState *fx, double drive_mm, double duration_s, double period_s,
                           double decay_time_s)
{
    const double w = 2.0 * GT_PI / period_s;
    const double sigma = 1.0 / decay_time_s;
    const double w0_sq = sigma * sigma + w * w;
    const double p = fx->seiche_x1 - drive_mm / w0_sq;
    const double envelope = exp(-sigma * duration_s);
    const double c = cos(w * duration_s);
    const double s = sin(w * duration_s) / w;
    const double p_new = envelope * ((c + sigma * s) * p + s * fx->seiche_x2);
    const double q_new = envelope * (-w0_sq * s * p + (c - sigma * s) * fx->seiche_x2);
    fx->seiche_x1 = p_new + drive_mm / w0_sq;
    fx->seiche_x2 = q_new;
}
#endif

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
    {
        const double w = 2.0 * GT_PI / PARAMETER(m, VR_FX_SEICHE_PERIOD_S);
        const double sigma = 1.0 / PARAMETER(m, VR_FX_SEICHE_DECAY_TIME_S);
        fx->seiche_x1 = (opening_mm - m->real[VR_OPENING_REF_MM]) / (sigma * sigma + w * w);
    }
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
    seiche_advance(&m->fx, gate_mm - m->real[VR_OPENING_REF_MM], duration_s,
                   PARAMETER(m, VR_FX_SEICHE_PERIOD_S), PARAMETER(m, VR_FX_SEICHE_DECAY_TIME_S));
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
    const double alpha = 1.0 / level_time_constant_s;
    const double beta = 1.0 / PARAMETER(m, VR_FX_LAG_TIME_CONSTANT_S);
    const double lo = alpha < beta ? alpha : beta;
    const double gap = beta > alpha ? (beta - alpha) : (alpha - beta);
    double phi, decay;
    if (gap == 0.0) {
        phi = beta * duration_s * exp(-lo * duration_s);
    } else {
        phi = beta * exp(-lo * duration_s) * (-expm1(-gap * duration_s)) / gap;
    }
    decay = exp(-beta * duration_s);
    m->fx.sensed_mm = level_target_mm + (m->fx.sensed_mm - level_target_mm) * decay +
                      level_excess_mm * phi;
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
    m->fx.sensed_mm = first_order(m->fx.sensed_mm, level_mm, duration_s,
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
        m->fx.inflow_mm = first_order(m->fx.inflow_mm, target, step_s,
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
    y += PARAMETER(m, VR_FX_SEICHE_AMPLITUDE_MM_PER_MM) *
         (2.0 * GT_PI / PARAMETER(m, VR_FX_SEICHE_PERIOD_S)) * m->fx.seiche_x2;
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
