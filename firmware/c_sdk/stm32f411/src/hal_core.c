/* HAL_Init, the 1 ms tick and the NVIC on the F411. HAL_Delay sleeps with WFI between
 * ticks, as a battery-minded firmware does: on the board it saves power, under hexhil's
 * emulator it lets virtual time jump to the next SysTick instead of executing the wait. */
#include "stm32f4xx_hal.h"

static volatile uint32_t uwTick;

static void set_priority(IRQn_Type irq, uint32_t priority)
{
    uint8_t value = (uint8_t)(priority << (8u - NVIC_PRIO_BITS));
    if ((int32_t)irq < 0)
        SCB->SHPR[((uint32_t)irq & 0xFu) - 4u] = value;
    else
        NVIC->IPR[irq] = value;
}

/* SysTick at 1 ms of SystemCoreClock; weak, as Cube's, for a firmware that ticks from a
 * timer instead. */
HAL_StatusTypeDef __weak HAL_InitTick(uint32_t TickPriority)
{
    SysTick->CSR = 0;
    SysTick->RVR = SystemCoreClock / 1000u - 1u;
    SysTick->CVR = 0;
    set_priority(SysTick_IRQn, TickPriority);
    SysTick->CSR = SysTick_CSR_CLKSOURCE | SysTick_CSR_TICKINT | SysTick_CSR_ENABLE;
    return HAL_OK;
}

void __weak HAL_MspInit(void) {}

HAL_StatusTypeDef HAL_Init(void)
{
    FLASH->ACR |= FLASH_ACR_PRFTEN | FLASH_ACR_ICEN | FLASH_ACR_DCEN;
    /* priority group 4: all four bits are preemption priority */
    SCB->AIRCR = SCB_AIRCR_VECTKEY | (3u << SCB_AIRCR_PRIGROUP_Pos);
    HAL_InitTick(TICK_INT_PRIORITY);
    HAL_MspInit();
    return HAL_OK;
}

void HAL_IncTick(void) { uwTick++; }

uint32_t HAL_GetTick(void) { return uwTick; }

void __weak SysTick_Handler(void) { HAL_IncTick(); }

void HAL_Delay(uint32_t Delay)
{
    uint32_t start = uwTick;
    uint32_t wait = Delay;
    if (wait < HAL_MAX_DELAY)
        wait++;   /* at least one whole tick more than asked, as Cube's */
    while (uwTick - start < wait)
        __WFI();
}

void HAL_NVIC_SetPriority(IRQn_Type IRQn, uint32_t PreemptPriority, uint32_t SubPriority)
{
    (void)SubPriority;   /* group 4 has none */
    set_priority(IRQn, PreemptPriority & 0xFu);
}

void HAL_NVIC_EnableIRQ(IRQn_Type IRQn)
{
    if ((int32_t)IRQn >= 0)
        NVIC->ISER[(uint32_t)IRQn >> 5] = 1u << ((uint32_t)IRQn & 31u);
}

void HAL_NVIC_DisableIRQ(IRQn_Type IRQn)
{
    if ((int32_t)IRQn >= 0) {
        NVIC->ICER[(uint32_t)IRQn >> 5] = 1u << ((uint32_t)IRQn & 31u);
        __DSB();
        __ISB();
    }
}

void HAL_NVIC_SystemReset(void)
{
    __DSB();
    SCB->AIRCR = SCB_AIRCR_VECTKEY | (SCB->AIRCR & (7u << SCB_AIRCR_PRIGROUP_Pos)) |
                 SCB_AIRCR_SYSRESETREQ;
    __DSB();
    for (;;) {
    }
}
