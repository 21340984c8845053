"""jsbsim-calib: build general-aviation JSBSim aircraft from geometry and calibrate them.

Library entry points (the CLI ``jsbsim-calib`` is a thin layer over these):

* :func:`jsbsim_calib.build.generate` - geometry -> JSBSim aircraft, engine and propeller files
* :class:`jsbsim_calib.fdm.Simulator` - an aircraft in JSBSim, trimmed to :class:`~jsbsim_calib.fdm.Condition`
* :func:`jsbsim_calib.data.load_dataset` and :func:`jsbsim_calib.evaluate.evaluate_dataset`
* :func:`jsbsim_calib.workflow.run_steady` - stage 1 calibration; :mod:`jsbsim_calib.factors` - the factors
"""
__version__ = "0.1.0"
