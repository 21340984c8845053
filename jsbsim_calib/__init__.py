"""jsbsim-calib: build general-aviation JSBSim aircraft from geometry and calibrate them.

Library entry points (the CLI ``jsbsim-calib`` is a thin layer over these):

* :func:`jsbsim_calib.generate.generate` - geometry -> JSBSim aircraft, engine and propeller files
* :class:`jsbsim_calib.jsbsim.simulator.Simulator` - an aircraft in JSBSim, trimmed to
  :class:`~jsbsim_calib.flight.condition.Condition`
* :func:`jsbsim_calib.data.load.load_dataset` and
  :func:`jsbsim_calib.evaluation.evaluate.evaluate_dataset`
* :func:`jsbsim_calib.calibration.workflow.run_steady` / ``run_trims`` / ``run_close_loop`` - the
  calibration chains (they return results); :func:`jsbsim_calib.jsbsim.product.write_calibrated`
  writes the product; :mod:`jsbsim_calib.factors` - the factors

The folders and what each may import: docs/architecture.md.
"""
__version__ = "0.1.0"
