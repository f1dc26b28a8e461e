/* simavr harness for the bench-pkm5 firmware: runs the ELF on an emulated ATmega2560 at 16 MHz, bridges UART0 to a
 * pseudo-terminal (its own bridge, polled every 100 us of emulated time: simavr's uart_pty part spins a thread)
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
 */
#define _GNU_SOURCE
#include <errno.h>
#include <fcntl.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#include "avr_ioport.h"
#include "avr_uart.h"
#include "sim_avr.h"
#include "sim_elf.h"

#define AXES 6
static const char STEP_PORTS[AXES] = {'E', 'G', 'H', 'H', 'B', 'B'};
static const int STEP_BITS[AXES] = {4, 5, 3, 5, 4, 6};
static const char DIR_PORTS[AXES] = {'E', 'E', 'H', 'H', 'B', 'B'};
static const int DIR_BITS[AXES] = {5, 3, 4, 6, 5, 7};

static avr_t *avr;
static FILE *events;
static int pty_master, pty_slave;
static int uart_xon;
static avr_irq_t *uart_input;
static uint8_t pending[256];
static size_t pending_len, pending_done;
/* Bytes the MCU sent that the pty could not take yet (the host was not scheduled: a loaded machine). A real
 * USB-serial adapter and the kernel buffer far more than a pty's 4 KiB, so nothing the firmware sends is dropped
 * here; only a host that stops reading for OUTBOX bytes loses the oldest, with a message. */
#define OUTBOX (1u << 20)
static uint8_t outbox[OUTBOX];
static size_t outbox_head, outbox_len;
static volatile sig_atomic_t stopping;
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
  static char line[2 * 128 + 1];
  static size_t length;
  uint8_t byte = (uint8_t)value;
  if (byte == '\n') {
    line[length] = '\0';
    fprintf(events, "%llu RX %s\n", (unsigned long long)avr->cycle, length ? line : "-");
    length = 0;
  } else if (length + 2 < sizeof line) {
    length += (size_t)sprintf(line + length, "%02x", byte);
  }
}

static void on_tx(struct avr_irq_t *irq, uint32_t value, void *param) {
  (void)irq;
  (void)param;
  if (outbox_len == OUTBOX) {
    fprintf(stderr, "harness: host not reading, %u bytes queued: oldest byte dropped\n", OUTBOX);
    outbox_head = (outbox_head + 1) % OUTBOX;
    outbox_len--;
  }
  outbox[(outbox_head + outbox_len++) % OUTBOX] = (uint8_t)value;
}

static void pump_output(void) {
  while (outbox_len > 0) {
    size_t run = outbox_head + outbox_len <= OUTBOX ? outbox_len : OUTBOX - outbox_head;
    ssize_t n = write(pty_master, outbox + outbox_head, run);
    if (n <= 0) {
      if (n < 0 && errno != EAGAIN && errno != EIO) perror("harness: pty write");
      return;  /* full (or no host yet): kept for the next poll */
    }
    outbox_head = (outbox_head + (size_t)n) % OUTBOX;
    outbox_len -= (size_t)n;
  }
}

static void on_xon(struct avr_irq_t *irq, uint32_t value, void *param) { (void)irq; (void)value; uart_xon = *(int *)param; }

static void pump_input(void) {
  if (pending_done == pending_len) {
    ssize_t n = read(pty_master, pending, sizeof pending);
    pending_len = n > 0 ? (size_t)n : 0;
    pending_done = 0;
  }
  while (uart_xon && pending_done < pending_len) avr_raise_irq(uart_input, pending[pending_done++]);
}

static void open_pty(void) {
  pty_master = posix_openpt(O_RDWR | O_NOCTTY);
  if (pty_master < 0 || grantpt(pty_master) || unlockpt(pty_master)) {
    perror("harness: pty");
    exit(1);
  }
  pty_slave = open(ptsname(pty_master), O_RDWR | O_NOCTTY);  /* held open: the pty outlives each host */
  struct termios raw;
  tcgetattr(pty_slave, &raw);
  cfmakeraw(&raw);
  tcsetattr(pty_slave, TCSANOW, &raw);
  fcntl(pty_master, F_SETFL, O_NONBLOCK);
}

static void no_sleep(avr_t *a, avr_cycle_count_t how_long) { (void)a; (void)how_long; }  /* paced below */

static void on_signal(int sig) { (void)sig; stopping = 1; }

static double wall_s(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return t.tv_sec + t.tv_nsec * 1e-9;
}

int main(int argc, char **argv) {
  if (argc != 3) {
    fprintf(stderr, "usage: %s FIRMWARE.elf EVENTS.txt\n", argv[0]);
    return 2;
  }
  elf_firmware_t firmware;
  memset(&firmware, 0, sizeof firmware);
  if (elf_read_firmware(argv[1], &firmware) != 0) {
    fprintf(stderr, "%s: cannot read firmware %s\n", argv[0], argv[1]);
    return 1;
  }
  avr = avr_make_mcu_by_name("atmega2560");
  if (!avr) return 1;
  avr_init(avr);
  avr_load_firmware(avr, &firmware);
  avr->frequency = 16000000;
  avr->sleep = no_sleep;
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
  static int on = 1, off = 0;
  uart_input = avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_INPUT);
  avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUTPUT), on_tx, NULL);
  avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUT_XON), on_xon, &on);
  avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUT_XOFF), on_xon, &off);
  open_pty();
  printf("PTY %s\n", ptsname(pty_master));
  fflush(stdout);
  signal(SIGTERM, on_signal);
  signal(SIGINT, on_signal);

  const avr_cycle_count_t pace = avr->frequency / 1000;  /* check the pace every emulated millisecond */
  const avr_cycle_count_t poll = avr->frequency / 10000;
  avr_cycle_count_t next_check = pace, next_poll = poll;
  double start = wall_s(), start0 = start;
  int state = cpu_Running;
  while (!stopping && state != cpu_Done && state != cpu_Crashed) {
    state = avr_run(avr);
    if (avr->cycle >= next_poll) {
      next_poll = avr->cycle + poll;
      pump_input();
      pump_output();
    }
    if (avr->cycle >= next_check) {
      next_check = avr->cycle + pace;
      double ahead = start + (double)avr->cycle / avr->frequency - wall_s();
      if (ahead > 0 && !getenv("HARNESS_FREE_RUN")) usleep((useconds_t)(ahead * 1e6));
      else if (ahead < -0.05) start -= ahead + 0.05;  /* a stall: emulated time slips instead of racing */
      if (avr->cycle % (100 * pace) < pace) fflush(events);
    }
  }
  fflush(events);
  fclose(events);
  fprintf(stderr, "harness: %.3f s emulated in %.3f s\n", (double)avr->cycle / avr->frequency, wall_s() - start0);
  _exit(state == cpu_Crashed ? 1 : 0);  /* the pty thread is not joined: it may sit in select() */
}
