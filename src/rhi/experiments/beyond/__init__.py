"""Experiments beyond the thesis: passivity, bilateral teleoperation with delay, intent estimation, spatial RHIs.

One module per study; each experiment's id is ``beyond.<function>`` (`rhi.report.reproduce`).
"""
