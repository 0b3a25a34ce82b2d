/* The few system calls newlib-nano needs on the board: stdout and stderr go to the console
 * (USART1 at 115200 baud on PA9, opened on the first write), malloc's heap grows from `end`
 * to stm32f411.ld's `_heap_limit` and reports ENOMEM beyond it, and the rest answer as a
 * board without files does. */
#include "stm32f4xx_hal.h"

#include <errno.h>
#include <sys/stat.h>

extern char end, _heap_limit;
static UART_HandleTypeDef console;

int _write(int fd, const char *buf, int len)
{
    if (fd != 1 && fd != 2) {
        errno = EBADF;
        return -1;
    }
    if (console.gState == HAL_UART_STATE_RESET) {
        console.Instance = USART1;
        console.Init.BaudRate = 115200;
        console.Init.Mode = UART_MODE_TX_RX;
        HAL_UART_Init(&console);
    }
    if (len > 0)
        HAL_UART_Transmit(&console, (const uint8_t *)buf, (uint16_t)len, HAL_MAX_DELAY);
    return len;
}

void *_sbrk(ptrdiff_t incr)
{
    static char *brk = &end;
    if (brk + incr > &_heap_limit || brk + incr < &end) {
        errno = ENOMEM;
        return (void *)-1;
    }
    char *old = brk;
    brk += incr;
    return old;
}

int _close(int fd) { (void)fd; return -1; }
int _read(int fd, char *buf, int len) { (void)fd; (void)buf; (void)len; return 0; }
int _lseek(int fd, int offset, int whence) { (void)fd; (void)offset; (void)whence; return 0; }
int _isatty(int fd) { return fd <= 2; }

int _fstat(int fd, struct stat *st)
{
    (void)fd;
    st->st_mode = S_IFCHR;
    return 0;
}
