"""Identify a twin from one step test, export it as an FMU and validate it through fmpy."""

import gatetwin

records = gatetwin.bundled_records_dir()
model = gatetwin.identify(records / "A.csv")  # a step test: FOPDT of gauge 3F
print(model)
print(model.at(flow_m3h=29.5, opening_mm=17.5))  # local K, T, L and the steady level
model.save("fopdt_3F.json")  # the same model file as `gatetwin identify`
fmu = model.export_fmu("fopdt_3F.fmu", backend="c")  # FMI 2.0 co-simulation
report = gatetwin.validate(fmu, [records / "A.csv"], fail_under={"fit_percent": 70})
print(report.markdown())
report.plot().savefig("validation.png")
raise SystemExit(0 if report.passed else 1)
