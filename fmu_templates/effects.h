/* Effect blocks around the dynamics: input -> input_blocks -> dynamics -> output_blocks -> output.
 *
 * input_blocks maps the commanded opening to the opening the gate really has (e.g. an actuator
 * rate limit); output_blocks maps the level the dynamics produce to the level the sensor
 * reports (e.g. a sensor lag). Both are the identity today: gatetwin exports only plants
 * without effect blocks. A block that keeps state stores it in ModelData (plant.h), so FMU
 * states carry it, and is advanced only after dynamics_check_step accepted the step.
 */
#ifndef GATETWIN_EFFECTS_H
#define GATETWIN_EFFECTS_H

static inline double input_blocks(double opening_mm, double step_s)
{
    (void)step_s;
    return opening_mm;
}

static inline double output_blocks(double level_mm)
{
    return level_mm;
}

#endif
