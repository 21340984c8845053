"""Calibration: the fit engine (:mod:`.fit`), point sets and residuals (:mod:`.points`), stage 1
(:mod:`.steady`), stage 2a (:mod:`.trims`) and stage 2b (:mod:`.dynamic`) of the method, residual
diagnosis (:mod:`.diagnose`), the effect library (:mod:`.effects`, ``effects/*.xml``), closing the
loop (:mod:`.closeloop`, :mod:`.closeloop_dynamic`), held-out validation (:mod:`.validation`,
:mod:`.validation_dynamic`), the chains that run the stages (:mod:`.workflow`) and model variants
side by side (:mod:`.variants`). The factors themselves are :mod:`jsbsim_calib.factors`."""
