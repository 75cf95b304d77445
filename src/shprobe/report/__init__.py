"""Layer 5, report: one self-contained HTML page about a light probe (images inlined, no
network) — what a pipeline TD attaches to a ticket. See `shprobe.report.probe`."""

from .probe import ProbeReport, ReportSettings, probe_report, write_report

__all__ = ["ProbeReport", "ReportSettings", "probe_report", "write_report"]
