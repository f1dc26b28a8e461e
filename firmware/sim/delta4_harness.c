/* simavr harness for the bench-delta4 firmware: runs the ELF on an emulated ATmega128 at 16 MHz, bridges UART0 to a
 * pseudo-terminal (bridge.c), records the servo PWM, laser, pot-ADC and received-byte events with their emulated
 * time, plays the two laser-grid screens (each a chain of 32 74LS166 shift registers, 256 OP521 phototransistors, on
 * the firmware's control lines, lit where the test says) and the four TLC548 pot ADCs (counts given by the test).
 *
 *   delta4_harness FIRMWARE.elf EVENTS.txt
 *
 * Prints "PTY /dev/pts/N" on stdout once the port is open. Reads lines from stdin to set the lit sensors:
 *   H 17 200      the horizontal screen's sensors 17 and 200 are lit by a laser (V: the vertical one; no index: none)
 *   A 76 81 0 255 the pot voltages of servos 1-4, as the 8-bit counts their TLC548 convert them to (default 0)
 * A sensor reads 1 only if it is lit and its screen's laser set is on at the parallel load (§5.5: lasers pulsed).
 * A TLC548 (datasheet SLAS066) puts the MSB of its last conversion on DATA OUT when CS falls and the next bit on each
 * I/O CLOCK falling edge; it samples its input until the 8th falling edge, whose value the next read returns.
 * EVENTS.txt gets one line per event (cycle / 16e6 = emulated time, s):
 *   <cycle> PWM <servo 1-4> <level>     a servo pulse edge (OC1A PB5, OC1B PB6, OC3A PE3, OC3B PE4)
 *   <cycle> LASER <1 H | 2 V> <level>   a laser-set enable edge (PC4, PC5)
 *   <cycle> RX <hex byte>               a byte received by UART0
 *   <cycle> ADC <clocks> <cs low> <setup> <min high> <min low> <c1> <c2> <c3> <c4>
 *                                       a read of the four TLC548, logged when CS rises: I/O CLOCK falling edges
 *                                       while CS was low, cycles CS was low, from CS low to the first rising edge,
 *                                       the shortest clock high and low times, the counts shifted out
 * Pins of the grid (firmware/delta4/delta4.c): CLOCK PC0, SHIFT/LOAD PC1 (low = load), CLOCK INHIBIT PC2, CLEAR PC3
 * (low = clear), QH of the last register of the horizontal / vertical chain on PA0 / PA1. Pot ADCs: CS PA2, I/O CLOCK
 * PA3 (shared), DATA OUT of servos 1-4 on PA4-PA7.
 */
#define _GNU_SOURCE
#include <fcntl.h>
#include <stdint.h>
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

/* the four TLC548 */
static uint8_t pot_input[SERVOS];      /* what the test feeds: the count each chip's input voltage converts to */
static uint8_t pot_result[SERVOS];     /* each chip's last conversion, shifted out at the next read */
static avr_irq_t *pot_out[SERVOS];
static uint8_t pot_cs = 1, pot_clock, pot_clocks, pot_shifted[SERVOS];
static uint64_t pot_cs_fall, pot_edge, pot_first_rise, pot_min_high, pot_min_low;
static long pot_ids[2] = {0, 1};

static void pot_drive(void) {  /* DATA OUT: bit 7 - clocks of the result while CS is low (high impedance: 0) */
  for (int i = 0; i < SERVOS; i++)
    avr_raise_irq(pot_out[i], !pot_cs && pot_clocks < 8 ? (pot_result[i] >> (7 - pot_clocks)) & 1 : 0);
}

static void on_pot_line(struct avr_irq_t *irq, uint32_t value, void *param) {
  (void)irq;
  uint8_t level = value & 1;
  uint64_t now = avr->cycle;
  if (*(long *)param == 0) {  /* CS */
    if (level == pot_cs) return;
    pot_cs = level;
    if (!level) {
      pot_cs_fall = pot_edge = now;
      pot_clocks = 0;
      pot_first_rise = 0;
      pot_min_high = pot_min_low = UINT64_MAX;
      for (int i = 0; i < SERVOS; i++) pot_shifted[i] = 0;
    } else {
      fprintf(events, "%llu ADC %u %llu %llu %llu %llu %u %u %u %u\n", (unsigned long long)now, pot_clocks,
              (unsigned long long)(now - pot_cs_fall), (unsigned long long)(pot_first_rise - pot_cs_fall),
              (unsigned long long)pot_min_high, (unsigned long long)pot_min_low, pot_shifted[0], pot_shifted[1],
              pot_shifted[2], pot_shifted[3]);
    }
    pot_drive();
    return;
  }
  if (level == pot_clock) return;  /* I/O CLOCK */
  pot_clock = level;
  if (pot_cs) return;
  if (level) {
    if (!pot_first_rise) pot_first_rise = now;
    else if (now - pot_edge < pot_min_low) pot_min_low = now - pot_edge;
    if (pot_clocks < 8)
      for (int i = 0; i < SERVOS; i++) pot_shifted[i] = (uint8_t)(pot_shifted[i] << 1 | ((pot_result[i] >> (7 - pot_clocks)) & 1));
  } else {
    if (now - pot_edge < pot_min_high) pot_min_high = now - pot_edge;
    if (++pot_clocks == 8) memcpy(pot_result, pot_input, sizeof pot_result);  /* hold: the next read's value */
  }
  pot_edge = now;
  pot_drive();
}

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
    if (line[0] == 'A') {
      char *p = line + 1, *end;
      for (int i = 0; i < SERVOS; i++, p = end) {
        long count = strtol(p, &end, 10);
        if (end == p) break;
        pot_input[i] = (uint8_t)(count < 0 ? 0 : count > 255 ? 255 : count);
      }
      continue;
    }
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
  for (int i = 0; i < 2; i++)  /* CS PA2, I/O CLOCK PA3 */
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ('A'), 2 + i), on_pot_line, &pot_ids[i]);
  for (int i = 0; i < SERVOS; i++) pot_out[i] = avr_io_getirq(avr, AVR_IOCTL_IOPORT_GETIRQ('A'), 4 + i);
  avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_INPUT), on_rx, NULL);
  fcntl(0, F_SETFL, fcntl(0, F_GETFL) | O_NONBLOCK);
  bridge_attach_uart(avr, '0');
  bridge_run(avr, events, read_commands);
  return 0;
}
