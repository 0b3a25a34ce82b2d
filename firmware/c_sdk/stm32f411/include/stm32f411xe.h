/* STM32F411xE registers at the level a firmware writes them: base addresses, register
 * layouts and the bits this SDK and its test firmwares use. Every value is a fact of ST's
 * RM0383 reference manual (and the ARMv7-M architecture manual for the core's System Control
 * Space), written down here in hexhil's own words; this is not ST's CMSIS device header.
 *
 * bxCAN1: the F411 has no CAN controller. hexhil's virtual board places bxCAN1 where the
 * STM32F405 has it (0x40006400, APB1ENR bit 25, IRQs 19-22) so that a firmware for a board
 * with a CAN transceiver can run; on a real F411 that address is reserved. */
#ifndef STM32F411XE_H
#define STM32F411XE_H

#include <stdint.h>

#define HX_REG volatile uint32_t

/* ---- memory map -------------------------------------------------------------------------- */
#define FLASH_BASE      0x08000000u   /* 512 KB */
#define SRAM1_BASE      0x20000000u   /* 128 KB */
#define TIM2_BASE       0x40000000u
#define TIM3_BASE       0x40000400u
#define TIM4_BASE       0x40000800u
#define TIM5_BASE       0x40000C00u
#define USART2_BASE     0x40004400u
#define CAN1_BASE       0x40006400u   /* hexhil's virtual board only: see above */
#define PWR_BASE        0x40007000u
#define USART1_BASE     0x40011000u
#define USART6_BASE     0x40011400u
#define SYSCFG_BASE     0x40013800u
#define EXTI_BASE       0x40013C00u
#define GPIOA_BASE      0x40020000u
#define GPIOB_BASE      0x40020400u
#define GPIOC_BASE      0x40020800u
#define RCC_BASE        0x40023800u
#define FLASH_R_BASE    0x40023C00u
#define DMA1_BASE       0x40026000u
#define DMA2_BASE       0x40026400u

/* ---- RCC --------------------------------------------------------------------------------- */
typedef struct {
    HX_REG CR, PLLCFGR, CFGR, CIR, AHB1RSTR, AHB2RSTR, RESERVED0[2];
    HX_REG APB1RSTR, APB2RSTR, RESERVED1[2];
    HX_REG AHB1ENR, AHB2ENR, RESERVED2[2];
    HX_REG APB1ENR, APB2ENR, RESERVED3[2];
    HX_REG AHB1LPENR, AHB2LPENR, RESERVED4[2];
    HX_REG APB1LPENR, APB2LPENR, RESERVED5[2];
    HX_REG BDCR, CSR, RESERVED6[2];
    HX_REG SSCGR, PLLI2SCFGR, RESERVED7, DCKCFGR;
} RCC_TypeDef;
#define RCC ((RCC_TypeDef *)RCC_BASE)

#define RCC_CR_HSION        (1u << 0)
#define RCC_CR_HSIRDY       (1u << 1)
#define RCC_CR_HSEON        (1u << 16)
#define RCC_CR_HSERDY       (1u << 17)
#define RCC_CR_PLLON        (1u << 24)
#define RCC_CR_PLLRDY       (1u << 25)
#define RCC_PLLCFGR_M_Pos   0u      /* /M: 2..63, the VCO input 1-2 MHz */
#define RCC_PLLCFGR_N_Pos   6u      /* xN: 50..432, the VCO output 100-432 MHz */
#define RCC_PLLCFGR_P_Pos   16u     /* /P: 0 = 2, 1 = 4, 2 = 6, 3 = 8 */
#define RCC_PLLCFGR_SRC_HSE (1u << 22)
#define RCC_PLLCFGR_Q_Pos   24u
#define RCC_CFGR_SW_Msk     3u
#define RCC_CFGR_SW_HSI     0u
#define RCC_CFGR_SW_HSE     1u
#define RCC_CFGR_SW_PLL     2u
#define RCC_CFGR_SWS_Pos    2u
#define RCC_CFGR_HPRE_Pos   4u      /* AHB: 0xxx = /1, 1000 = /2 ... */
#define RCC_CFGR_PPRE1_Pos  10u     /* APB1: 0xx = /1, 100 = /2, 101 = /4, 110 = /8, 111 = /16 */
#define RCC_CFGR_PPRE2_Pos  13u     /* APB2: the same code */
#define RCC_AHB1ENR_GPIOAEN (1u << 0)
#define RCC_AHB1ENR_GPIOBEN (1u << 1)
#define RCC_AHB1ENR_GPIOCEN (1u << 2)
#define RCC_AHB1ENR_DMA1EN  (1u << 21)
#define RCC_AHB1ENR_DMA2EN  (1u << 22)
#define RCC_APB1ENR_TIM2EN  (1u << 0)
#define RCC_APB1ENR_TIM3EN  (1u << 1)
#define RCC_APB1ENR_TIM4EN  (1u << 2)
#define RCC_APB1ENR_TIM5EN  (1u << 3)
#define RCC_APB1ENR_USART2EN (1u << 17)
#define RCC_APB1ENR_CAN1EN  (1u << 25)   /* hexhil's virtual board only */
#define RCC_APB1ENR_PWREN   (1u << 28)
#define RCC_APB2ENR_USART1EN (1u << 4)
#define RCC_APB2ENR_USART6EN (1u << 5)
#define RCC_APB2ENR_SYSCFGEN (1u << 14)

#define HSI_VALUE 16000000u

/* ---- FLASH interface, PWR ---------------------------------------------------------------- */
typedef struct { HX_REG ACR, KEYR, OPTKEYR, SR, CR, OPTCR; } FLASH_TypeDef;
#define FLASH ((FLASH_TypeDef *)FLASH_R_BASE)
#define FLASH_ACR_LATENCY_Msk 0xFu      /* wait states: 3 at 90-100 MHz, 2.7-3.6 V */
#define FLASH_ACR_PRFTEN (1u << 8)
#define FLASH_ACR_ICEN   (1u << 9)
#define FLASH_ACR_DCEN   (1u << 10)

typedef struct { HX_REG CR, CSR; } PWR_TypeDef;
#define PWR ((PWR_TypeDef *)PWR_BASE)
#define PWR_CR_VOS_Pos 14u              /* 3 = scale 1 (up to 100 MHz) */

/* ---- GPIO -------------------------------------------------------------------------------- */
struct hx_gpio_port {
    HX_REG MODER, OTYPER, OSPEEDR, PUPDR, IDR, ODR, BSRR, LCKR, AFR[2];
};
#define GPIOA ((GPIO_TypeDef *)GPIOA_BASE)
#define GPIOB ((GPIO_TypeDef *)GPIOB_BASE)
#define GPIOC ((GPIO_TypeDef *)GPIOC_BASE)

/* ---- USART ------------------------------------------------------------------------------- */
struct hx_usart {
    HX_REG SR, DR, BRR, CR1, CR2, CR3, GTPR;
};
#define USART1 ((USART_TypeDef *)USART1_BASE)
#define USART2 ((USART_TypeDef *)USART2_BASE)
#define USART6 ((USART_TypeDef *)USART6_BASE)
#define USART_SR_PE    (1u << 0)
#define USART_SR_FE    (1u << 1)
#define USART_SR_NE    (1u << 2)
#define USART_SR_ORE   (1u << 3)
#define USART_SR_IDLE  (1u << 4)
#define USART_SR_RXNE  (1u << 5)
#define USART_SR_TC    (1u << 6)
#define USART_SR_TXE   (1u << 7)
#define USART_CR1_RE     (1u << 2)
#define USART_CR1_TE     (1u << 3)
#define USART_CR1_RXNEIE (1u << 5)
#define USART_CR1_TCIE   (1u << 6)
#define USART_CR1_TXEIE  (1u << 7)
#define USART_CR1_PCE    (1u << 10)
#define USART_CR1_M      (1u << 12)
#define USART_CR1_UE     (1u << 13)
#define USART_CR1_OVER8  (1u << 15)
#define USART_CR2_STOP_Pos 12u
#define USART_CR2_CLKEN  (1u << 11)
#define USART_CR2_LINEN  (1u << 14)
#define USART_CR3_EIE    (1u << 0)
#define USART_CR3_IREN   (1u << 1)
#define USART_CR3_HDSEL  (1u << 3)
#define USART_CR3_SCEN   (1u << 5)
#define USART_CR3_DMAR   (1u << 6)
#define USART_CR3_DMAT   (1u << 7)

/* ---- DMA (two controllers, eight streams each) ------------------------------------------- */
typedef struct { HX_REG CR, NDTR, PAR, M0AR, M1AR, FCR; } DMA_Stream_TypeDef;
typedef struct { HX_REG LISR, HISR, LIFCR, HIFCR; DMA_Stream_TypeDef S[8]; } DMA_TypeDef;
#define DMA1 ((DMA_TypeDef *)DMA1_BASE)
#define DMA2 ((DMA_TypeDef *)DMA2_BASE)
#define DMA_SxCR_EN      (1u << 0)
#define DMA_SxCR_TEIE    (1u << 2)
#define DMA_SxCR_TCIE    (1u << 4)
#define DMA_SxCR_DIR_M2P (1u << 6)       /* DIR = 01: memory to peripheral; 00: to memory */
#define DMA_SxCR_MINC    (1u << 10)
#define DMA_SxCR_CHSEL_Pos 25u
/* The flags of stream s: LISR/LIFCR for 0-3, HISR/HIFCR for 4-7, at bit 0, 6, 16, 22. */
#define DMA_FLAG_SHIFT(s) ((uint32_t)((((s) & 2u) ? 16u : 0u) + (((s) & 1u) ? 6u : 0u)))
#define DMA_FLAG_TCIF  (1u << 5)
#define DMA_FLAG_TEIF  (1u << 3)
#define DMA_FLAG_ALL   0x3Du             /* FEIF, DMEIF, TEIF, HTIF, TCIF */

/* ---- EXTI, SYSCFG ------------------------------------------------------------------------ */
typedef struct { HX_REG IMR, EMR, RTSR, FTSR, SWIER, PR; } EXTI_TypeDef;
#define EXTI ((EXTI_TypeDef *)EXTI_BASE)
typedef struct { HX_REG MEMRMP, PMC, EXTICR[4], RESERVED[2], CMPCR; } SYSCFG_TypeDef;
#define SYSCFG ((SYSCFG_TypeDef *)SYSCFG_BASE)

/* ---- TIM2-TIM5 (general-purpose, TIM2 and TIM5 32-bit) ----------------------------------- */
typedef struct {
    HX_REG CR1, CR2, SMCR, DIER, SR, EGR, CCMR1, CCMR2, CCER, CNT, PSC, ARR, RESERVED0;
    HX_REG CCR1, CCR2, CCR3, CCR4, RESERVED1, DCR, DMAR, OR;
} TIM_TypeDef;
#define TIM2 ((TIM_TypeDef *)TIM2_BASE)
#define TIM3 ((TIM_TypeDef *)TIM3_BASE)
#define TIM4 ((TIM_TypeDef *)TIM4_BASE)
#define TIM5 ((TIM_TypeDef *)TIM5_BASE)
#define TIM_CR1_CEN  (1u << 0)
#define TIM_DIER_UIE (1u << 0)
#define TIM_SR_UIF   (1u << 0)
#define TIM_EGR_UG   (1u << 0)

/* ---- bxCAN1 (hexhil's virtual board; not on a real F411) --------------------------------- */
typedef struct { HX_REG TIR, TDTR, TDLR, TDHR; } CAN_TxMailBox_TypeDef;
typedef struct { HX_REG RIR, RDTR, RDLR, RDHR; } CAN_FIFOMailBox_TypeDef;
typedef struct { HX_REG FR1, FR2; } CAN_FilterRegister_TypeDef;
typedef struct {
    HX_REG MCR, MSR, TSR, RF0R, RF1R, IER, ESR, BTR, RESERVED0[88];
    CAN_TxMailBox_TypeDef TX[3];
    CAN_FIFOMailBox_TypeDef RX[2];
    HX_REG RESERVED1[12];
    HX_REG FMR, FM1R, RESERVED2, FS1R, RESERVED3, FFA1R, RESERVED4, FA1R, RESERVED5[8];
    CAN_FilterRegister_TypeDef FILTER[28];
} CAN_TypeDef;
#define CAN1 ((CAN_TypeDef *)CAN1_BASE)

/* ---- the core: SysTick, NVIC, SCB, DWT, FPU (ARMv7-M) ------------------------------------ */
typedef struct { HX_REG CSR, RVR, CVR, CALIB; } SysTick_TypeDef;
#define SysTick ((SysTick_TypeDef *)0xE000E010u)
#define SysTick_CSR_ENABLE    (1u << 0)
#define SysTick_CSR_TICKINT   (1u << 1)
#define SysTick_CSR_CLKSOURCE (1u << 2)   /* 1: the processor clock */
#define SysTick_CSR_COUNTFLAG (1u << 16)

typedef struct {
    HX_REG ISER[8], RESERVED0[24], ICER[8], RESERVED1[24], ISPR[8], RESERVED2[24];
    HX_REG ICPR[8], RESERVED3[24], IABR[8], RESERVED4[56];
    volatile uint8_t IPR[240];
} NVIC_TypeDef;
#define NVIC ((NVIC_TypeDef *)0xE000E100u)
#define NVIC_PRIO_BITS 4u                 /* the F4 implements the top 4 bits of a priority */

typedef struct {
    HX_REG CPUID, ICSR, VTOR, AIRCR, SCR, CCR;
    volatile uint8_t SHPR[12];            /* handlers 4..15; SHPR[n - 4] is handler n's */
    HX_REG SHCSR, CFSR, HFSR, DFSR, MMFAR, BFAR, AFSR;
} SCB_TypeDef;
#define SCB ((SCB_TypeDef *)0xE000ED00u)
#define SCB_ICSR_PENDSTSET  (1u << 26)
#define SCB_ICSR_PENDSVSET  (1u << 28)
#define SCB_AIRCR_VECTKEY   (0x05FAu << 16)
#define SCB_AIRCR_PRIGROUP_Pos 8u
#define SCB_AIRCR_SYSRESETREQ (1u << 2)
#define SCB_SCR_SLEEPDEEP   (1u << 2)
#define SCB_CPACR (*(HX_REG *)0xE000ED88u)  /* CP10, CP11 full access: bits 20-23 set */
#define CoreDebug_DEMCR (*(HX_REG *)0xE000EDFCu)
#define CoreDebug_DEMCR_TRCENA (1u << 24)

typedef struct { HX_REG CTRL, CYCCNT; } DWT_TypeDef;
#define DWT ((DWT_TypeDef *)0xE0001000u)
#define DWT_CTRL_CYCCNTENA (1u << 0)

/* System exceptions as negative numbers, device interrupts from 0 (the vector table's
 * position minus 16). */
typedef enum {
    MemoryManagement_IRQn = -12, BusFault_IRQn = -11, UsageFault_IRQn = -10,
    SVCall_IRQn = -5, PendSV_IRQn = -2, SysTick_IRQn = -1,
    EXTI0_IRQn = 6, EXTI1_IRQn = 7, EXTI2_IRQn = 8, EXTI3_IRQn = 9, EXTI4_IRQn = 10,
    DMA1_Stream0_IRQn = 11, DMA1_Stream5_IRQn = 16, DMA1_Stream6_IRQn = 17,
    CAN1_TX_IRQn = 19, CAN1_RX0_IRQn = 20, CAN1_RX1_IRQn = 21, CAN1_SCE_IRQn = 22,
    EXTI9_5_IRQn = 23, TIM2_IRQn = 28, TIM3_IRQn = 29, TIM4_IRQn = 30,
    USART1_IRQn = 37, USART2_IRQn = 38, EXTI15_10_IRQn = 40, DMA1_Stream7_IRQn = 47,
    TIM5_IRQn = 50, DMA2_Stream0_IRQn = 56, DMA2_Stream1_IRQn = 57, DMA2_Stream2_IRQn = 58,
    DMA2_Stream5_IRQn = 68, DMA2_Stream6_IRQn = 69, DMA2_Stream7_IRQn = 70, USART6_IRQn = 71,
    FPU_IRQn = 81
} IRQn_Type;

#ifndef __weak
#define __weak __attribute__((weak))   /* a definition the firmware's own replaces */
#endif
#define __enable_irq()  __asm volatile ("cpsie i" : : : "memory")
#define __disable_irq() __asm volatile ("cpsid i" : : : "memory")
#define __WFI()         __asm volatile ("wfi" : : : "memory")
#define __DSB()         __asm volatile ("dsb 0xF" : : : "memory")
#define __ISB()         __asm volatile ("isb 0xF" : : : "memory")

#endif /* STM32F411XE_H */
