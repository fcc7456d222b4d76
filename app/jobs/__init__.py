"""Processing jobs: asking for one (``queue.enqueue``: the rules shared by the API and ``chakamo reprocess``),
the unit of work (``work``), the engines that run it (``inprocess`` threads inside ``chakamo serve``,
``celery_engine`` workers through Redis) and cohort reprocessing (``reprocess``).  Nothing here imports
``app.web``."""
