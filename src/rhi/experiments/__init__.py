"""Thesis experiments, one package per chapter and one module per experiment: functions that return `Result` objects.

An experiment's id is its chapter and its function, ``ch3.psychophysics`` for
`rhi.experiments.ch3.discrimination.psychophysics`: the chapter is the package (ch3 … ch7,
beyond) or module (appa, appb) directly under `rhi.experiments`, and the `Result` the
experiment returns carries the same name (`rhi.report.reproduce` lists them). What several
experiments build the same way lives in `rhi.experiments.setups` (hands, runs, progress), in
each chapter's ``setup`` module (its constants, controllers and start configurations) and in
`rhi.experiments.identification` (the §3.5/§6.4 identification protocol). No plotting here.
"""
