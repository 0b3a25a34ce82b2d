"""Hardware abstraction: ``Board`` objects shaped after MicroPython's machine API.

hal/base.py declares the contract (``Board``, ``CAN``, ``Switch``) every back end
subclasses: ``sim.Board`` talks to the host simulator over the link (virtual time,
docs/link.md), ``serial.Board`` drives a real or pty serial line under the unix port,
``board.Board`` the STM32F411 robot. No module here imports the application.
"""
