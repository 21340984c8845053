"""Reference data: schemas and validation (:mod:`.schemas`), POH tables (:mod:`.poh`), flight-test
snapshots and flap climbs (:mod:`.flighttest`), Garmin G1000 logs (:mod:`.g1000`, :mod:`.logs`),
and :func:`.load.load_dataset`, which recognises a file's kind and loads it. Each kind also
states the trim conditions its rows stand for and the model values it compares."""
