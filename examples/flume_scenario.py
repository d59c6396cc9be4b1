"""Run the virtual flume on a scenario of your own and identify a twin from its record."""

import numpy as np

import gatetwin
from gatetwin.flume.experiments import Scenario, run_scenario

# a step test at Q = 40 m3/h: the gate 20 -> 25 mm at t = 300 s, logged for 20 minutes
gate = ((0.0, 20.0), (300.0, 25.0))
scenario = Scenario("my_step", ((0.0, 40.0),), gate, 1200.0, seed=7, test="step")
path = run_scenario(scenario).write("my_step.csv")  # CSV and sidecar, the record format
record = gatetwin.read_record(path)
model = gatetwin.identify(record)
print(model, model.at(flow_m3h=40.0, opening_mm=22.5), sep="\n")
commanded = np.where(record.time_s < 300.0, 20.0, 25.0)
result = model.simulate(commanded, 40.0, record.time_s)
error = result.level_mm - record.levels_mm["3F"]
print(f"free-run RMSE against the flume: {np.sqrt(np.nanmean(error**2)):.2f} mm")
figure = result.plot()
figure.axes[0].plot(record.time_s, record.levels_mm["3F"], ".", ms=2, label="flume")
figure.savefig("my_step.png")
