"""The interactive view of a fit (``turbinefit view``): one self-contained HTML page.

* :mod:`turbinefit.view.scene` -- what the page shows, as data (the turbine's solid with
  coverage colours, frusta, paths, skeletons, photos with the fitted skeleton
  reprojected, the first viewpoint), from arrays in memory;
* :mod:`turbinefit.view.page` -- the HTML file: ``page.html``, ``viewer.css``,
  ``viewer.js`` and the vendored three.js (``vendor/``) inlined with the data.

Above the core, beside :mod:`turbinefit.plots` (whose colours and coverage scale it
shares); the job that reads the folders is :mod:`turbinefit.jobs.view`.
"""
