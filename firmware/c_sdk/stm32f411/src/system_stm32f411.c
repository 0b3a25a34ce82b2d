/* The clock tree of the robot's board (RM0383 section 6): SYSCLK 100 MHz from the 16 MHz HSI
 * through the main PLL (/M 16 = 1 MHz VCO input, xN 200 = 200 MHz VCO, /P 2), AHB 100 MHz,
 * APB1 50 MHz (its maximum), APB2 100 MHz, three flash wait states and voltage scale 1 as the
 * datasheet asks at 100 MHz. SystemInit runs it from Reset_Handler before main, so a
 * CubeIDE-style main.c that only calls HAL_Init runs at the robot's speed. The frequencies
 * are read back from the registers, not assumed. */
#include "stm32f4xx_hal.h"

#ifndef HSE_VALUE
#define HSE_VALUE 8000000u   /* the board's crystal, if a firmware switches to HSE */
#endif

uint32_t SystemCoreClock = HSI_VALUE;

void SystemClock_Config100MHz(void)
{
    hx_rcc_enable(&RCC->APB1ENR, RCC_APB1ENR_PWREN);
    PWR->CR = (PWR->CR & ~(3u << PWR_CR_VOS_Pos)) | (3u << PWR_CR_VOS_Pos);
    FLASH->ACR = 3u | FLASH_ACR_PRFTEN | FLASH_ACR_ICEN | FLASH_ACR_DCEN;
    while ((FLASH->ACR & FLASH_ACR_LATENCY_Msk) != 3u) {
    }
    RCC->CR |= RCC_CR_HSION;
    while (!(RCC->CR & RCC_CR_HSIRDY)) {
    }
    if ((RCC->CFGR >> RCC_CFGR_SWS_Pos & 3u) == RCC_CFGR_SW_PLL) {   /* off the PLL first */
        RCC->CFGR &= ~RCC_CFGR_SW_Msk;
        while ((RCC->CFGR >> RCC_CFGR_SWS_Pos & 3u) != RCC_CFGR_SW_HSI) {
        }
    }
    RCC->CR &= ~RCC_CR_PLLON;
    while (RCC->CR & RCC_CR_PLLRDY) {
    }
    RCC->PLLCFGR = (16u << RCC_PLLCFGR_M_Pos) | (200u << RCC_PLLCFGR_N_Pos) |
                   (0u << RCC_PLLCFGR_P_Pos) | (4u << RCC_PLLCFGR_Q_Pos);
    RCC->CR |= RCC_CR_PLLON;
    while (!(RCC->CR & RCC_CR_PLLRDY)) {
    }
    RCC->CFGR = (0u << RCC_CFGR_HPRE_Pos) | (4u << RCC_CFGR_PPRE1_Pos) |
                (0u << RCC_CFGR_PPRE2_Pos) | RCC_CFGR_SW_PLL;
    while ((RCC->CFGR >> RCC_CFGR_SWS_Pos & 3u) != RCC_CFGR_SW_PLL) {
    }
    SystemCoreClockUpdate();
}

void __weak SystemInit(void)
{
    SCB_CPACR |= 0xFu << 20;   /* the FPU: CP10, CP11 full access */
    SystemClock_Config100MHz();
}

uint32_t HAL_RCC_GetSysClockFreq(void)
{
    uint32_t sws = RCC->CFGR >> RCC_CFGR_SWS_Pos & 3u;
    if (sws == RCC_CFGR_SW_HSE)
        return HSE_VALUE;
    if (sws != RCC_CFGR_SW_PLL)
        return HSI_VALUE;
    uint32_t cfg = RCC->PLLCFGR;
    uint32_t in = (cfg & RCC_PLLCFGR_SRC_HSE) ? HSE_VALUE : HSI_VALUE;
    uint32_t m = cfg >> RCC_PLLCFGR_M_Pos & 0x3Fu, n = cfg >> RCC_PLLCFGR_N_Pos & 0x1FFu;
    uint32_t p = ((cfg >> RCC_PLLCFGR_P_Pos & 3u) + 1u) * 2u;
    return m ? (uint32_t)((uint64_t)in / m * n / p) : HSI_VALUE;
}

uint32_t HAL_RCC_GetHCLKFreq(void)
{
    static const uint8_t shift[16] = {0, 0, 0, 0, 0, 0, 0, 0, 1, 2, 3, 4, 6, 7, 8, 9};
    return HAL_RCC_GetSysClockFreq() >> shift[RCC->CFGR >> RCC_CFGR_HPRE_Pos & 0xFu];
}

/* CMSIS's: SystemCoreClock (the core's clock, HCLK) from the registers as they are now. */
void SystemCoreClockUpdate(void) { SystemCoreClock = HAL_RCC_GetHCLKFreq(); }

static uint32_t apb(uint32_t code)
{
    uint32_t hclk = HAL_RCC_GetHCLKFreq();
    return code < 4u ? hclk : hclk >> (code - 3u);
}

uint32_t HAL_RCC_GetPCLK1Freq(void) { return apb(RCC->CFGR >> RCC_CFGR_PPRE1_Pos & 7u); }
uint32_t HAL_RCC_GetPCLK2Freq(void) { return apb(RCC->CFGR >> RCC_CFGR_PPRE2_Pos & 7u); }
