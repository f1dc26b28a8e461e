/* simavr harness for the bench-delta4 firmware: runs the ELF on an emulated ATmega128 at 16 MHz, bridges UART0 to a
 * pseudo-terminal (bridge.c), records the servo PWM, laser and received-byte events with their emulated time, and
 * plays the two laser-grid screens: each a chain of 32 74LS166 shift registers (256 OP521 phototransistors) on the
 * firmware's control lines, lit where the test says.
 *
 *   delta4_harness FIRMWARE.elf EVENTS.txt
 *
 * Prints "PTY /dev/pts/N" on stdout once the port is open. Reads lines from stdin to set the lit sensors:
 *   H 17 200      the horizontal screen's sensors 17 and 200 are lit by a laser (V: the vertical one; no index: none)
 * A sensor reads 1 only if it is lit and its screen's laser set is on at the parallel load (§5.5: lasers pulsed).
 * EVENTS.txt gets one line per event (cycle / 16e6 = emulated time, s):
 *   <cycle> PWM <servo 1-4> <level>     a servo pulse edge (OC1A PB5, OC1B PB6, OC3A PE3, OC3B PE4)
 *   <cycle> LASER <1 H | 2 V> <level>   a laser-set enable edge (PC4, PC5)
 *   <cycle> RX <hex byte>               a byte received by UART0
 * Pins of the grid (firmware/delta4/delta4.c): CLOCK PC0, SHIFT/LOAD PC1 (low = load), CLOCK INHIBIT PC2, CLEAR PC3
 * (low = clear), QH of the last register of the horizontal / vertical chain on PA0 / PA1.
 */
#define _GNU_SOURCE
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "avr_ioport.h"
#include "avr_uart.h"
#include "bridge.h"

#define SERVOS 4
#define SENSORS 256
enum { PIN_CLOCK, PIN_SHIFT_LOAD, PIN_INHIBIT, PIN_CLEAR, PIN_LASER_H, PIN_LASER_V };
static const char PWM_PORTS[SERVOS] = {'B', 'B', 'E', 'E'};
static const int PWM_BITS[SERVOS] = {5, 6, 3, 4};

static avr_t *avr;
static FILE *events;
static long ids[SERVOS + 6];
static uint8_t lit[2][SENSORS];        /* what the test shines on each screen */
static uint8_t chain[2][SENSORS];      /* the registers' contents, chain[s][k] = bit out after k clocks */
static int position;                   /* clocks since the load */
static uint8_t control[6] = {0, 1, 1, 1, 0, 0};
static avr_irq_t *data_pin[2];

static void drive_outputs(void) {
  for (int s = 0; s < 2; s++) avr_raise_irq(data_pin[s], position < SENSORS ? chain[s][position] : 0);
}

static void on_pwm(struct avr_irq_t *irq, uint32_t value, void *param) {
  (void)irq;
  fprintf(events, "%llu PWM %ld %u\n", (unsigned long long)avr->cycle, *(long *)param + 1, value & 1);
}

static void on_control(struct avr_irq_t *irq, uint32_t value, void *param) {
  (void)irq;
  int pin = (int)(*(long *)param - SERVOS);
  uint8_t level = value & 1, before = control[pin];
  control[pin] = level;
  if (pin == PIN_LASER_H || pin == PIN_LASER_V) {
    if (level != before) fprintf(events, "%llu LASER %d %u\n", (unsigned long long)avr->cycle, pin - PIN_LASER_H + 1, level);
    return;
  }
  if (pin == PIN_CLEAR && !level) {
    memset(chain, 0, sizeof chain);
  } else if (pin == PIN_CLOCK && level && !before && !control[PIN_INHIBIT]) {
    if (!control[PIN_SHIFT_LOAD]) {  /* parallel load: a phototransistor conducts only while its laser is on */
      for (int s = 0; s < 2; s++)
        for (int k = 0; k < SENSORS; k++) chain[s][k] = lit[s][k] && control[PIN_LASER_H + s] && control[PIN_CLEAR];
      position = 0;
    } else if (position < SENSORS) {
      position++;
    }
  }
  drive_outputs();
}

static void read_commands(void) {  /* stdin lines "H i j ..." / "V i j ..." */
  static char line[4096];
  static size_t length;
  char c;
  while (read(0, &c, 1) == 1) {
    if (c != '\n') {
      if (length + 1 < sizeof line) line[length++] = c;
      continue;
    }
    line[length] = '\0';
    length = 0;
    int screen = line[0] == 'H' ? 0 : line[0] == 'V' ? 1 : -1;
    if (screen < 0) continue;
    memset(lit[screen], 0, SENSORS);
    for (char *p = line + 1, *end; ; p = end) {
      long index = strtol(p, &end, 10);
      if (end == p) break;
      if (index >= 0 && index < SENSORS) lit[screen][index] = 1;
    }
  }
}

static void on_rx(struct avr_irq_t *irq, uint32_t value, void *param) {
  (void)irq;
  (void)param;
  fprintf(events, "%llu RX %02x\n", (unsigned long long)avr->cycle, value & 0xFF);
}

int main(int argc, char **argv) {
  if (argc != 3) {
    fprintf(stderr, "usage: %s FIRMWARE.elf EVENTS.txt\n", argv[0]);
    return 2;
  }
  avr = bridge_load(argv[1], "atmega128");
  events = fopen(argv[2], "w");
  if (!events) {
    perror(argv[2]);
    return 1;
  }
  for (long i = 0; i < SERVOS + 6; i++) {
    ids[i] = i;
    avr_irq_t *pin = i < SERVOS ? avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ(PWM_PORTS[i]), PWM_BITS[i])
                                : avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ('C'), (int)(i - SERVOS));
    avr_irq_register_notify(pin, i < SERVOS ? on_pwm : on_control, &ids[i]);
  }
  for (int s = 0; s < 2; s++) data_pin[s] = avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ('A'), s);
  avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_INPUT), on_rx, NULL);
  fcntl(0, F_SETFL, fcntl(0, F_GETFL) | O_NONBLOCK);
  bridge_attach_uart(avr, '0');
  bridge_run(avr, events, read_commands);
  return 0;
}
