# The STM32F411xE: the port's F4 series, its F411 alternate-function table and linker scripts
# (the firmware in sector 0 and from 0x08020000, /flash between them).
MCU_SERIES = f4
CMSIS_MCU = STM32F411xE
AF_FILE = boards/stm32f411_af.csv
LD_FILES = boards/stm32f411.ld boards/common_ifs.ld
TEXT0_ADDR = 0x08000000
TEXT1_ADDR = 0x08020000

# The UART and flash interrupt handlers run from RAM: a flash erase stalls code run from flash.
MICROPY_HW_ENABLE_ISR_UART_FLASH_FUNCS_IN_RAM = 1
