"""Research command lines beside the clinical product: foot-mounted pedestrian dead reckoning (``walk``, with
its IEZ reader ``walk_ingestion``) and the Markovian Kalman filters on multi-segment CSVs (``markov``)."""
