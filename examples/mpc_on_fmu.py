"""Close the loop: the MPC holds the level of an exported FMU through a set-point change."""

import gatetwin
from gatetwin.mpc import FmuCore, MpcController

model = gatetwin.identify(gatetwin.bundled_records_dir() / "B.csv")  # FOPDT at 72.5 m³/h
plant = FmuCore(model.export_fmu("fopdt_3F.fmu", backend="c"))  # the twin as the process
mpc = MpcController(model.plant)
flow, opening = 72.5, 30.0
level = start = plant.start(opening, flow)
mpc.setpoint_mm = start  # hold the level we start at, then lower it by 20 mm
for k in range(300):  # 300 samples of 1.2 s
    if k == 50:
        mpc.setpoint_mm = start - 20.0
    opening = mpc.step(level, flow)
    level = plant.advance(opening, flow)
plant.cleanup()
print(f"set-point {mpc.setpoint_mm:.1f} mm, level {level:.1f} mm, opening {opening:.1f} mm")
