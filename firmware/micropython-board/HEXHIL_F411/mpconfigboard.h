// MicroPython's stm32 port for the hexapod's STM32F411 board (docs/micropython-on-the-chip.md).
// The facts are the board's (docs/elf-firmware.md) and RM0383's; the option names are the
// port's (ports/stm32/mpconfigboard_common.h).
#define MICROPY_HW_BOARD_NAME       "HEXHIL-F411"
#define MICROPY_HW_MCU_NAME         "STM32F411xE"

// No user button: a board without one must say so, or the port's boot-mode selection reads
// its (absent) pin. The internal-flash filesystem (/flash, 64 KB from 0x08004000) and the
// RTC (on LSI: the board has no 32.768 kHz crystal) are on.
#define MICROPY_HW_HAS_SWITCH       (0)
#define MICROPY_HW_HAS_FLASH        (1)
#define MICROPY_HW_ENABLE_RTC       (1)
#define MICROPY_HW_RTC_USE_LSE      (0)

// SYSCLK 100 MHz, the F411's most (RM0383 6.2): the 25 MHz HSE crystal / M 25 = 1 MHz into
// the VCO, x N 200 = 200 MHz, / P 2. Q 4 (48 MHz would need N 192: there is no USB here).
// Three wait states for 90-100 MHz at 2.7-3.6 V (RM0383 table 5).
#define MICROPY_HW_CLK_PLLM         (25)
#define MICROPY_HW_CLK_PLLN         (200)
#define MICROPY_HW_CLK_PLLP         (RCC_PLLP_DIV2)
#define MICROPY_HW_CLK_PLLQ         (4)
#define MICROPY_HW_FLASH_LATENCY    (FLASH_LATENCY_3)

// The REPL on USART1 (PA9 TX, PA10 RX, AF7). UART(2) is the AX-12 line: PA2 sends and PA3
// listens, the 74HC126/74HC04 buffer joining both to the single wire, PA1 its direction
// (Pin('A1'), high while sending). UART(6) on PC6/PC7 is free for the user.
#define MICROPY_HW_UART1_TX         (pin_A9)
#define MICROPY_HW_UART1_RX         (pin_A10)
#define MICROPY_HW_UART2_TX         (pin_A2)
#define MICROPY_HW_UART2_RX         (pin_A3)
#define MICROPY_HW_UART6_TX         (pin_C6)
#define MICROPY_HW_UART6_RX         (pin_C7)
#define MICROPY_HW_UART_REPL        PYB_UART_1
#define MICROPY_HW_UART_REPL_BAUD   115200
