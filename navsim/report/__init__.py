"""Reports: a run's ``report.pdf`` and PNGs (:mod:`~navsim.report.pages`) and its interactive
``report.html`` (:mod:`~navsim.report.html`), a replay's (:mod:`~navsim.report.replay`) and a
sweep's figure (:mod:`~navsim.report.sweep`).

:mod:`~navsim.report.html` (with its parts, :mod:`~navsim.report.html_parts`, and the run
picker, :mod:`~navsim.report.picker`) is attached lazily (``lazy_loader``, SPEC 1): Bokeh takes
about 0.3-0.5 s to import, paid only by a process that writes a page."""

import lazy_loader

__getattr__, __dir__, __all__ = lazy_loader.attach(__name__, submodules=["html", "html_parts", "picker"])
