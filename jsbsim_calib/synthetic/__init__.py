"""Synthetic reference data flown by a truth aircraft: flight-test snapshots (:mod:`.snapshots`),
time histories from a maneuver plan (:mod:`.maneuvers`, plans in ``plans/*.toml``), and truth
aircraft with terms the model does not declare (:mod:`.truth`), for tests and experiments."""
