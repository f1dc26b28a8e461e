/* simavr harness for the bench-pkm5 firmware: runs the ELF on an emulated ATmega2560 at 16 MHz, bridges UART0 to a
 * pseudo-terminal (bridge.c, polled every 100 us of emulated time)
 * and records every STEP / DIR / EN pin edge and every received newline
 * with its emulated time.
 *
 *   pkm5_harness FIRMWARE.elf EVENTS.txt
 *
 * Prints "PTY /dev/pts/N" on stdout once the port is open. EVENTS.txt gets one line per event:
 *   <cycle> STEP|DIR|EN <axis 1-6> <level 0|1>      a pin edge
 *   <cycle> RX <hex bytes>|-                          a line received by UART0, at its '\n' (hex, first 128 bytes)
 * with cycle / 16e6 the emulated time in seconds. Emulated time is paced to wall time (the host's timeouts are
 * wall-clock), catching up at most 50 ms after a stall. Runs until killed (SIGTERM / SIGINT flush the file).
 * HARNESS_SCRIPT=FILE: script mode (bridge.c), host lines at set emulated times, replies logged as TX lines.
 */
#include <stdio.h>
#include <stdlib.h>

#include "avr_ioport.h"
#include "avr_uart.h"
#include "bridge.h"
#include "sim_avr.h"

#define AXES 6
static const char STEP_PORTS[AXES] = {'E', 'G', 'H', 'H', 'B', 'B'};
static const int STEP_BITS[AXES] = {4, 5, 3, 5, 4, 6};
static const char DIR_PORTS[AXES] = {'E', 'E', 'H', 'H', 'B', 'B'};
static const int DIR_BITS[AXES] = {5, 3, 4, 6, 5, 7};

static avr_t *avr;
static FILE *events;
static long pin_ids[3 * AXES];

static void on_pin(struct avr_irq_t *irq, uint32_t value, void *param) {
  (void)irq;
  long id = *(long *)param;
  static const char *const KINDS[] = {"STEP", "DIR", "EN"};
  fprintf(events, "%llu %s %ld %u\n", (unsigned long long)avr->cycle, KINDS[id / AXES], id % AXES + 1, value & 1);
}

static void on_rx(struct avr_irq_t *irq, uint32_t value, void *param) {
  (void)irq;
  (void)param;
  bridge_log_line_byte(events, avr->cycle, "RX", (uint8_t)value);
}

int main(int argc, char **argv) {
  if (argc != 3) {
    fprintf(stderr, "usage: %s FIRMWARE.elf EVENTS.txt\n", argv[0]);
    return 2;
  }
  avr = bridge_load(argv[1], "atmega2560");
  events = fopen(argv[2], "w");
  if (!events) {
    perror(argv[2]);
    return 1;
  }
  for (int i = 0; i < AXES; i++) {
    char ports[3] = {STEP_PORTS[i], DIR_PORTS[i], 'A'};
    int bits[3] = {STEP_BITS[i], DIR_BITS[i], i};
    for (int k = 0; k < 3; k++) {
      pin_ids[k * AXES + i] = k * AXES + i;
      avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ(ports[k]), bits[k]), on_pin,
                              &pin_ids[k * AXES + i]);
    }
  }
  avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_INPUT), on_rx, NULL);
  bridge_attach_uart(avr, '0');
  bridge_run(avr, events, NULL);
}
