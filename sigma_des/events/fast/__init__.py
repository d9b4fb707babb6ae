"""The compiled message core: a backend of the engine (docs/concepts/engines.md).

``layout`` declares its state by name (``declare``: how a declared state is built);
``primitives`` holds the queueing, slot, draw and link operations; ``queue`` the event
queue (a merge of sorted runs), ``fanout`` and ``channel`` the batches that stand for
many of its entries, ``tally`` the events run by class;
``broker``, ``node`` and ``server`` the handlers (``job`` a node's job and its cost,
``warp`` time-warp rollbacks); ``loop`` the entry points and the event loop; ``tables``
the draw tables Python fills (``frame_draws`` a trigger's rows in one pass,
``rollbacks`` the rollback draws and the batched re-simulation); ``driver`` the Python
side the engine composes (``setup`` its state arrays of one run; ``entries`` and
``handle`` the loop's entry points it calls without numba's dispatch, on the state
unboxed once); ``support`` what the core reproduces.
"""
