"""The ground floor, imported by every other folder and importing none of them: one error
hierarchy (:mod:`.errors`), unit constants (:mod:`.units`), small linear algebra and the bounded
least-squares solver (:mod:`.numerics`), several files replaced as one unit (:mod:`.commit`), a
run's temporary folders (:mod:`.tempdirs`) and one interface for independent work
(:mod:`.executor`)."""
