"""Caches that spare repeated work: the ideal fidelity run on disk, numba kernels warmed up.

* :mod:`sigma_des.cache.ideal` — the ideal run, computed once per scenario and shared by
  every method, process and run (``SIGMA_DES_CACHE_DIR``).
* :mod:`sigma_des.cache.paths` — the cache root both caches live under.
* :mod:`sigma_des.cache.sources` — the fingerprint of the sources compiled code depends
  on, which names numba's cache directory (:mod:`sigma_des.jitcache`).

``sigma-des warmup`` (:mod:`sigma_des.warmup`), which fills numba's cache by running
tiny comparisons, sits above :mod:`sigma_des.api`, not here.
"""
