"""Everything that knows JSBSim: its XML vocabulary (:mod:`.xml`), the aircraft's functions as
data (:mod:`.equations`), the aircraft, engine and propeller files and the run script
(:mod:`.aircraft`, :mod:`.propulsion`, :mod:`.templates`), the product on disk (:mod:`.product`),
the simulator (:mod:`.simulator`), the trim solver (:mod:`.trim`) and probes of a loaded
aircraft (:mod:`.probes`). The flight conditions it trims to are :mod:`jsbsim_calib.flight`'s."""
