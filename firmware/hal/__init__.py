"""Hardware abstraction: ``Board`` objects shaped after MicroPython's machine API.

``sim.Board`` talks to the host simulator over the link (virtual time); ``board.Board``
drives the STM32F411 robot. Both give: ``uart`` (``write``, ``transact``), six
``switches`` (``value()``), ``can`` (``send``, ``any``, ``recv``), ``ticks_us``,
``ticks_diff``, ``ticks_add``, ``sleep_until``, ``perf_us``, ``event`` and ``config``.
"""
