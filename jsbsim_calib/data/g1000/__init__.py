"""Garmin G1000 flight logs: reading (:mod:`.parse`) and quasi-steady segments (:mod:`.segments`)."""
