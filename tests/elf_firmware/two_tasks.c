/* Two tasks on one core, switched by PendSV every SysTick (1 ms), the way an RTOS does it:
 * SVC starts the first task on its own stack (PSP), SysTick pends PendSV, and PendSV saves
 * r4-r11 (and s16-s31 when the task used the FPU) on the outgoing task's stack and loads the
 * other's. Each task counts its runs and a float of its own, sleeps in WFI until the next
 * tick, and every 100 ms prints a console line; a float that does not match the count
 * means a context switch lost a register. Built with the SDK (HAL_Init's SysTick, printf on
 * USART1); its SysTick_Handler replaces the SDK's and calls HAL_IncTick. */
#include "stm32f4xx_hal.h"

#include <stdio.h>

#define STACK_WORDS 512
#define FRAME_WORDS 17          /* r4-r11, EXC_RETURN; then r0-r3, r12, lr, pc, xPSR */

static uint32_t stacks[2][STACK_WORDS] __attribute__((aligned(8)));
static uint32_t *task_sp[2];
static volatile uint32_t current;
static volatile uint32_t runs[2];
static volatile uint32_t started;   /* SysTick runs from HAL_Init; tasks only after SVC */

void SysTick_Handler(void)
{
    HAL_IncTick();
    if (started)
        SCB->ICSR = SCB_ICSR_PENDSVSET;
}

/* Called by PendSV with the outgoing task's saved stack; returns the incoming task's. */
uint32_t *hx_switch_task(uint32_t *sp)
{
    task_sp[current] = sp;
    current ^= 1u;
    return task_sp[current];
}

uint32_t *hx_first_task(void)
{
    started = 1;
    return task_sp[0];
}

__attribute__((naked)) void PendSV_Handler(void)
{
    __asm volatile(
        "mrs r0, psp\n"
        "tst lr, #0x10\n"
        "it eq\n"
        "vstmdbeq r0!, {s16-s31}\n"
        "stmdb r0!, {r4-r11, lr}\n"
        "bl hx_switch_task\n"
        "ldmia r0!, {r4-r11, lr}\n"
        "tst lr, #0x10\n"
        "it eq\n"
        "vldmiaeq r0!, {s16-s31}\n"
        "msr psp, r0\n"
        "bx lr\n");
}

__attribute__((naked)) void SVC_Handler(void)
{
    __asm volatile(
        "bl hx_first_task\n"
        "ldmia r0!, {r4-r11, lr}\n"
        "msr psp, r0\n"
        "bx lr\n");
}

static void task(uint32_t me)
{
    float sum = 0.0f;
    uint32_t next_ms = 100;
    for (;;) {
        runs[me]++;
        sum += 0.5f;
        if (HAL_GetTick() >= next_ms) {
            __disable_irq();
            printf("task %c: %lu runs at %lu ms%s\n", me ? 'b' : 'a', (unsigned long)runs[me],
                   (unsigned long)next_ms, sum == 0.5f * (float)runs[me] ? "" : " CORRUPT");
            __enable_irq();
            next_ms += 100;
        }
        __WFI();
    }
}

static void task_a(void) { task(0); }
static void task_b(void) { task(1); }

static void task_exit(void)
{
    for (;;) {
    }
}

static void prepare(uint32_t i, void (*entry)(void))
{
    uint32_t *sp = &stacks[i][STACK_WORDS - FRAME_WORDS];
    for (int k = 0; k < FRAME_WORDS; k++)
        sp[k] = 0;
    sp[8] = 0xFFFFFFFDu;                       /* EXC_RETURN: thread mode, PSP, no FPU frame */
    sp[9 + 5] = (uint32_t)(uintptr_t)task_exit;           /* lr */
    sp[9 + 6] = (uint32_t)(uintptr_t)entry;               /* pc */
    sp[9 + 7] = 0x01000000u;                               /* xPSR: Thumb */
    task_sp[i] = sp;
}

int main(void)
{
    HAL_Init();
    printf("two tasks: starting\n");
    HAL_NVIC_SetPriority(PendSV_IRQn, 15, 0);
    HAL_NVIC_SetPriority(SVCall_IRQn, 0, 0);
    prepare(0, task_a);
    prepare(1, task_b);
    __asm volatile("svc 0");
    for (;;) {   /* never here: the tasks own the core */
    }
}
