"""Exports of a calibrated aircraft to where pilots fly it: a FlightGear aircraft folder
(:mod:`.flightgear`) and a FlightGear session driven over its property server (:mod:`.fgfs`)."""
