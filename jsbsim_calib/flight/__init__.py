"""Flight as plain data, below everything that flies it: a flight condition to trim to and the
trimmed state (:mod:`.condition`). The data kinds (:mod:`jsbsim_calib.data`) state their rows as
these without knowing JSBSim; :mod:`jsbsim_calib.jsbsim` trims and flies them."""
