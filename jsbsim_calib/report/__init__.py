"""Presenting results: Markdown reports with figures (:mod:`.markdown`), the figures themselves
(:mod:`.plots`: each takes ``ax=`` and returns its figure), the verdicts against the accuracy
targets (:mod:`.verdicts`), the console's text tables (:mod:`.text`) and what a long command
shows while it runs (:mod:`.progress`). The reports of one result each are named for it: the
Part 60 report (:mod:`.part60_report`), the held-out validation report
(:mod:`.validation_report`), the model-variant comparison (:mod:`.variants_report`), the
time-history close-loop report (:mod:`.closeloop_dynamic_report`) and the close-loop report's
section on synthesized terms (:mod:`.synthesis_section`). They draw results; they run nothing."""
