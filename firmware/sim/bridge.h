/* The pty bridge of the simavr harnesses (harness.c for the pkm5, delta4_harness.c). Loads an ELF on an emulated MCU, bridges one UART to a pseudo-terminal (polled every 100 us of
 * emulated time: simavr's uart_pty part spins a thread) and runs the core paced to wall time. */
#ifndef BENCH_SIM_BRIDGE_H
#define BENCH_SIM_BRIDGE_H
#include <stdio.h>

#include "sim_avr.h"

/* The MCU `mcu` (simavr name) at 16 MHz running `elf`; exits with a message when either cannot be had. */
avr_t *bridge_load(const char *elf, const char *mcu);
/* Bridge UART `uart` ('0', '1') to a new pty and print "PTY /dev/pts/N" on stdout. */
void bridge_attach_uart(avr_t *avr, char uart);
/* Run until SIGTERM / SIGINT or a crash, paced to wall time (catching up at most 50 ms after a stall; no pacing
 * with HARNESS_FREE_RUN set), calling `every_poll` (may be NULL) every 100 us of emulated time and flushing `events`
 * every 100 ms; prints the emulated / wall time on stderr and exits (1 after a crash). */
void bridge_run(avr_t *avr, FILE *events, void (*every_poll)(void));
/* One byte of a line the MCU received ("RX") or sent ("TX"): at its '\n' the line goes to `events` as
 * `<cycle> KIND <hex of its first 128 bytes>` (`-` when empty). */
void bridge_log_line_byte(FILE *events, avr_cycle_count_t cycle, const char *kind, uint8_t byte);
#endif
