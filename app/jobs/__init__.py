"""Processing jobs: the unit of work (``work``), the engines that run it (``inprocess`` threads inside
``chakamo serve``, ``celery_engine`` workers through Redis) and cohort reprocessing (``reprocess``)."""
