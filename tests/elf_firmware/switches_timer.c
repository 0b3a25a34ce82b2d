/* The leg switches by interrupt and a hardware timer: PB0-PB5 in GPIO_MODE_IT_RISING_FALLING
 * (EXTI lines 0-5 through SYSCFG) queue each edge with its SysTick time, TIM2 counts update
 * interrupts at 1 kHz (100 MHz timer clock: APB1 at /2 doubles it, RM0383 6.2; prescaler 100,
 * auto-reload 1000), and the main loop sleeps in WFI and prints what came: a line per switch
 * edge and, at 500 ms, how many TIM2 updates there were. */
#include "stm32f4xx_hal.h"

#include <stdio.h>

static const char *const LEG[6] = {"LF", "LM", "LH", "RF", "RM", "RH"};
static volatile uint32_t queue[64];            /* leg << 28 | pressed << 27 | time_ms */
static volatile uint32_t head, tail, tim2_updates;

void HAL_GPIO_EXTI_Callback(uint16_t GPIO_Pin)
{
    for (uint32_t leg = 0; leg < 6; leg++) {
        if (GPIO_Pin == (1u << leg)) {
            uint32_t pressed = !(GPIOB->IDR & GPIO_Pin);   /* to ground: low is pressed */
            queue[head++ % 64u] = leg << 28 | pressed << 27 | HAL_GetTick();
        }
    }
}

void TIM2_IRQHandler(void)
{
    TIM2->SR = ~TIM_SR_UIF;
    tim2_updates++;
}

int main(void)
{
    GPIO_InitTypeDef io = {0};
    HAL_Init();
    __HAL_RCC_GPIOB_CLK_ENABLE();
    io.Pin = GPIO_PIN_0 | GPIO_PIN_1 | GPIO_PIN_2 | GPIO_PIN_3 | GPIO_PIN_4 | GPIO_PIN_5;
    io.Mode = GPIO_MODE_IT_RISING_FALLING;
    io.Pull = GPIO_PULLUP;
    HAL_GPIO_Init(GPIOB, &io);
    static const IRQn_Type lines[] = {EXTI0_IRQn, EXTI1_IRQn, EXTI2_IRQn, EXTI3_IRQn,
                                      EXTI4_IRQn, EXTI9_5_IRQn, TIM2_IRQn};
    for (unsigned i = 0; i < sizeof lines / sizeof lines[0]; i++) {
        HAL_NVIC_SetPriority(lines[i], 6, 0);
        HAL_NVIC_EnableIRQ(lines[i]);
    }
    hx_rcc_enable(&RCC->APB1ENR, RCC_APB1ENR_TIM2EN);
    TIM2->PSC = 100u - 1u;
    TIM2->ARR = 1000u - 1u;
    TIM2->EGR = TIM_EGR_UG;                   /* load PSC now; the update flag it sets ... */
    TIM2->SR = ~TIM_SR_UIF;                   /* ... is not an update of the count */
    TIM2->DIER = TIM_DIER_UIE;
    uint32_t start_ms = HAL_GetTick(), tim2_start = tim2_updates;
    TIM2->CR1 = TIM_CR1_CEN;
    int reported = 0;
    for (;;) {
        __WFI();
        while (tail != head) {
            uint32_t e = queue[tail++ % 64u];
            printf("switch %s %s at %lu ms\n", LEG[e >> 28], (e >> 27 & 1u) ? "pressed"
                   : "released", (unsigned long)(e & 0x7FFFFFFu));
        }
        if (!reported && HAL_GetTick() - start_ms >= 500u) {
            printf("tim2: %lu updates in 500 ms\n", (unsigned long)(tim2_updates - tim2_start));
            reported = 1;
        }
    }
}
