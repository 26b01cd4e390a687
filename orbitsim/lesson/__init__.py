"""``orbitsim demo``: the lesson, one orbit and three ways to step time.

* :mod:`~orbitsim.lesson.run`: the three schemes, the dt sweep and their metrics;
* :mod:`~orbitsim.lesson.output`: the two figures, summary.json and the report;
* :mod:`~orbitsim.lesson.page` and :mod:`~orbitsim.lesson.page_template`: ``lesson.html``, the page to
  play with.
"""
