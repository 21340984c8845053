"""Physics of the aircraft in SI, without JSBSim or XML: the standard atmosphere and air data,
geometry, airfoil polars, strip-theory aerodynamics, blade-element propeller, piston engine and
mass properties. One pure function per model; the chain that runs them is
:mod:`jsbsim_calib.generate`."""
