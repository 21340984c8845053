"""Presenting results: Markdown reports with figures (:mod:`.markdown`), the figures themselves
(:mod:`.plots`: each takes ``ax=`` and returns its figure), the verdicts against the accuracy
targets (:mod:`.verdicts`) and the console's text tables (:mod:`.text`)."""
