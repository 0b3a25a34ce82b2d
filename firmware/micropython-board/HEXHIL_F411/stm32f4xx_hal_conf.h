// ST's HAL configuration for the board: its oscillators, then the port's common F4 settings.
#ifndef MICROPY_INCLUDED_STM32F4XX_HAL_CONF_H
#define MICROPY_INCLUDED_STM32F4XX_HAL_CONF_H

#define HSE_VALUE (25000000)               // the board's crystal
#define LSE_VALUE (32768)                  // not fitted; the HAL wants the value
#define EXTERNAL_CLOCK_VALUE (12288000)    // I2S_CKIN, unused
#define HSE_STARTUP_TIMEOUT (100)          // ms
#define LSE_STARTUP_TIMEOUT (5000)         // ms

#include "boards/stm32f4xx_hal_conf_base.h"

#endif
