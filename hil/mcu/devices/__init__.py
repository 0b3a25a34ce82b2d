"""The peripherals described as data (hil/mcu/registers.py), a file each: their register
maps from RM0383 and, where the firmware needs it, their behaviour. hil/mcu/platform.py
places each at its address."""
