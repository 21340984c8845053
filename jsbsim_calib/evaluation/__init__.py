"""A model held against reference data, without fitting it: the data kinds' trims compared
(:mod:`.evaluate`), the dynamic tests flown and measured (:mod:`.evaluate_dynamic`), recorded
time histories replayed (:mod:`.timehistory_compare`), every Part 60 test judged
(:mod:`.part60`), the physics checks (:mod:`.physics_checks`), a logged flight's weight
(:mod:`.weight_estimate`), the regression check after a hand edit (:mod:`.regress`) and a folder
of G1000 logs (:mod:`.fleet`). The fits (:mod:`jsbsim_calib.calibration`) stand above it."""
