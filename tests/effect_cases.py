"""What the effect-block tests share: one material example of every block."""

#: One material example of every block (flow_dependent_gain: FOPDT only).
EXAMPLES = {
    "actuator_rate_limit": {"rate_mm_per_s": 0.5},
    "actuator_backlash": {"deadband_mm": 1.5},
    "opening_nonlinearity": {"gain_slope_per_mm": -0.03},
    "flow_dependent_gain": {"gain_slope_per_m3h": -0.01, "time_constant_slope_per_m3h": -0.012,
                            "flow_ref_m3h": 50.0},
    "seiche": {"period_s": 9.0, "decay_time_s": 25.0, "amplitude_mm_per_mm": 0.8},
    "inflow_disturbance": {"gain_mm_per_m3h": 2.0, "time_constant_s": 30.0, "flow_ref_m3h": 50.0},
    "sensor_drift": {"rate_mm_per_s": 0.01},
    "sensor_lag": {"time_constant_s": 6.0},
}  # fmt: skip
