/* HAL_GPIO_* on the virtual board's wiring: GPIOB pins 0-5 read the leg switches (pressed:
 * GPIO_PIN_RESET, as a switch to ground with a pull-up), GPIOA pin 1 drives the servo
 * line's direction buffer (its level goes to the board core, hal_board.c, where the UART
 * reads it); other pins keep what was written. */
#include "stm32f4xx_hal.h"
#include "hal_board.h"
#include "hexhil_link.h"

GPIO_TypeDef hexhil_gpioa = {'A'}, hexhil_gpiob = {'B'}, hexhil_gpioc = {'C'};

static uint16_t out_level[3];   /* ODR of ports A, B, C */

static int port_index(const GPIO_TypeDef *p) { return (int)(p->id - 'A'); }

void HAL_GPIO_Init(GPIO_TypeDef *GPIOx, GPIO_InitTypeDef *GPIO_Init)
{
    (void)GPIOx;
    (void)GPIO_Init;
    hx_board_start();
}

GPIO_PinState HAL_GPIO_ReadPin(GPIO_TypeDef *GPIOx, uint16_t GPIO_Pin)
{
    hx_board_poll();
    if (GPIOx->id == HX_SWITCH_PORT && (GPIO_Pin & 0x3Fu))
        return (hx_link_switches() & GPIO_Pin) ? GPIO_PIN_RESET : GPIO_PIN_SET;
    return (out_level[port_index(GPIOx)] & GPIO_Pin) ? GPIO_PIN_SET : GPIO_PIN_RESET;
}

/* A write to the direction pin turns the line (the board core keeps its level). */
static void written(const GPIO_TypeDef *GPIOx, uint16_t GPIO_Pin)
{
    if (GPIOx->id == HX_DIR_PORT && (GPIO_Pin & HX_DIR_PIN))
        hx_direction_set((out_level[HX_DIR_PORT - 'A'] & HX_DIR_PIN) != 0);
}

void HAL_GPIO_WritePin(GPIO_TypeDef *GPIOx, uint16_t GPIO_Pin, GPIO_PinState PinState)
{
    if (PinState == GPIO_PIN_SET)
        out_level[port_index(GPIOx)] |= GPIO_Pin;
    else
        out_level[port_index(GPIOx)] &= (uint16_t)~GPIO_Pin;
    written(GPIOx, GPIO_Pin);
}

void HAL_GPIO_TogglePin(GPIO_TypeDef *GPIOx, uint16_t GPIO_Pin)
{
    out_level[port_index(GPIOx)] ^= GPIO_Pin;
    written(GPIOx, GPIO_Pin);
}
