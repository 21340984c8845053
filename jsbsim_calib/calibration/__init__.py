"""Calibration: the fit engine (:mod:`.fit`), point sets and residuals (:mod:`.points`), stage 1
(:mod:`.steady`) and stage 2a (:mod:`.trims`) of the method, residual diagnosis
(:mod:`.diagnose`), the effect library (:mod:`.effects`, ``effects/*.xml``) and closing the loop
(:mod:`.closeloop`). The factors themselves are :mod:`jsbsim_calib.factors`."""
