/* See bridge.h. */
#define _GNU_SOURCE
#include "bridge.h"

#include <errno.h>
#include <fcntl.h>
#include <signal.h>
#include <stdlib.h>
#include <string.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#include "avr_extint.h"
#include "avr_uart.h"
#include "sim_elf.h"

static int pty_master, pty_slave;
static int uart_xon;
static avr_irq_t *uart_input;
static uint8_t pending[256];
static size_t pending_len, pending_done;
static volatile sig_atomic_t stopping;
/* Bytes the MCU sent that the pty could not take yet (the host was not scheduled: a loaded machine). A real
 * USB-serial adapter and the kernel buffer far more than a pty's 4 KiB, so nothing the firmware sends is dropped
 * here; only a host that stops reading for OUTBOX bytes loses the oldest, with a message. */
#define OUTBOX (1u << 20)
static uint8_t outbox[OUTBOX];
static size_t outbox_head, outbox_len;

/* Script mode (HARNESS_SCRIPT=FILE): no host on the pty; the UART gets the bytes of FILE's lines
 * `<emulated us> <hex bytes>` at those emulated times (in file order, as fast as the UART takes them), the run goes
 * unpaced and ends at a line `<emulated us> END`; every line the MCU sends goes to the events file as
 * `<cycle> TX <hex>`. Deterministic: the safety tests place host lines to the microsecond of emulated time. */
typedef struct {
  avr_cycle_count_t at;
  uint8_t *bytes;
  size_t length;  /* SIZE_MAX: END */
} script_line_t;
static script_line_t *script;
static size_t script_count, script_next, script_done;
static avr_t *script_avr;
static FILE *script_events;

static void load_script(const char *path) {
  FILE *f = fopen(path, "r");
  if (!f) {
    perror(path);
    exit(1);
  }
  size_t capacity = 0;
  char text[4096];
  while (fgets(text, sizeof text, f)) {
    unsigned long long us;
    char hex[4000];
    if (sscanf(text, "%llu %3999s", &us, hex) != 2) continue;
    if (script_count == capacity) script = realloc(script, (capacity = capacity ? 2 * capacity : 1024) * sizeof *script);
    script_line_t *line = &script[script_count++];
    line->at = (avr_cycle_count_t)(us * 16);  /* 16 MHz */
    if (strcmp(hex, "END") == 0) {
      line->bytes = NULL;
      line->length = SIZE_MAX;
      continue;
    }
    line->length = strlen(hex) / 2;
    line->bytes = malloc(line->length + 1);
    for (size_t i = 0; i < line->length; i++) sscanf(hex + 2 * i, "%2hhx", &line->bytes[i]);
  }
  fclose(f);
}

void bridge_log_line_byte(FILE *events, avr_cycle_count_t cycle, const char *kind, uint8_t byte) {
  static char lines[2][2 * 128 + 1];
  static size_t lengths[2];
  int slot = kind[0] == 'T';
  char *line = lines[slot];
  if (byte == '\n') {
    line[lengths[slot]] = '\0';
    fprintf(events, "%llu %s %s\n", (unsigned long long)cycle, kind, lengths[slot] ? line : "-");
    lengths[slot] = 0;
  } else if (lengths[slot] + 2 < sizeof lines[slot]) {
    lengths[slot] += (size_t)sprintf(line + lengths[slot], "%02x", byte);
  }
}

/* Feeds the script's due bytes; returns 0 once its END is due. */
static int pump_script(avr_t *avr) {
  while (script_next < script_count && script[script_next].at <= avr->cycle) {
    script_line_t *line = &script[script_next];
    if (line->length == SIZE_MAX) return 0;
    while (uart_xon && script_done < line->length) avr_raise_irq(uart_input, line->bytes[script_done++]);
    if (script_done < line->length) return 1;  /* the UART's FIFO is full: the rest at the next poll */
    script_next++;
    script_done = 0;
  }
  return script_next < script_count;
}

static void on_tx(struct avr_irq_t *irq, uint32_t value, void *param) {
  (void)irq;
  (void)param;
  if (script) {
    bridge_log_line_byte(script_events, script_avr->cycle, "TX", (uint8_t)value);
    return;
  }
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
  if (!uart_input) return;
  if (pending_done == pending_len) {
    ssize_t n = read(pty_master, pending, sizeof pending);
    pending_len = n > 0 ? (size_t)n : 0;
    pending_done = 0;
  }
  while (uart_xon && pending_done < pending_len) avr_raise_irq(uart_input, pending[pending_done++]);
}

static void no_sleep(avr_t *a, avr_cycle_count_t how_long) { (void)a; (void)how_long; }  /* paced below */

static void on_signal(int sig) { (void)sig; stopping = 1; }

static double wall_s(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return t.tv_sec + t.tv_nsec * 1e-9;
}

avr_t *bridge_load(const char *elf, const char *mcu) {
  static elf_firmware_t firmware;
  memset(&firmware, 0, sizeof firmware);
  if (elf_read_firmware(elf, &firmware) != 0) {
    fprintf(stderr, "harness: cannot read firmware %s\n", elf);
    exit(1);
  }
  avr_t *avr = avr_make_mcu_by_name(mcu);
  if (!avr) {
    fprintf(stderr, "harness: simavr has no MCU %s\n", mcu);
    exit(1);
  }
  avr_init(avr);
  avr_load_firmware(avr, &firmware);
  avr->frequency = 16000000;
  avr->sleep = no_sleep;
  /* simavr emulates a low-level INTn (ISC = 00, the reset default) by polling the pin every cycle while it is low,
   * enabled or not: on the ATmega2560 INT4 / INT5 are PE4 / PE5 (pkm5 STEP 1 / DIR 1), on the ATmega128 INT4 is PE4
   * (delta4 servo 4), outputs that sit low, and the poll took over 90 % of the harness's CPU (the pkm5 ran 15x slower
   * than without; the delta4's idle sleep could not skip ahead). Neither firmware enables an external interrupt (EIMSK
   * stays 0), so the poll only ever set an INTF flag nobody reads; without it a low level raises INTn once, at the
   * falling edge. A firmware that uses a low-level INTn would need the strict polling back. */
  for (uint8_t i = 0; i < EXTINT_COUNT; i++) avr_extint_set_strict_lvl_trig(avr, i, 0);
  return avr;
}

void bridge_attach_uart(avr_t *avr, char uart) {
  static int on = 1, off = 0;
  /* simavr's UART defaults off: STDIO echoes every line the MCU sends on stdout, a pipe the tests stop reading after
   * the PTY line (the harness would block once 64 KiB filled it); POLL_SLEEP (a usleep on status-register reads, for
   * a simulation that does not pace itself) is not wanted either: bridge_run paces. */
  uint32_t uart_flags = 0;
  avr_ioctl(avr, AVR_IOCTL_UART_SET_FLAGS(uart), &uart_flags);
  uart_input = avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ(uart), UART_IRQ_INPUT);
  avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ(uart), UART_IRQ_OUTPUT), on_tx, NULL);
  avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ(uart), UART_IRQ_OUT_XON), on_xon, &on);
  avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ(uart), UART_IRQ_OUT_XOFF), on_xon, &off);
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
  printf("PTY %s\n", ptsname(pty_master));
  fflush(stdout);
}

void bridge_run(avr_t *avr, FILE *events, void (*every_poll)(void)) {
  signal(SIGTERM, on_signal);
  signal(SIGINT, on_signal);
  const avr_cycle_count_t pace = avr->frequency / 1000;  /* check the pace every emulated millisecond */
  const avr_cycle_count_t poll = avr->frequency / 10000;
  avr_cycle_count_t next_check = pace, next_poll = poll;
  double start = wall_s(), start0 = start;
  int state = cpu_Running;
  const char *script_path = getenv("HARNESS_SCRIPT");
  if (script_path) {
    script_avr = avr;
    script_events = events;
    load_script(script_path);
  }
  while (!stopping && state != cpu_Done && state != cpu_Crashed) {
    state = avr_run(avr);
    if (avr->cycle >= next_poll) {
      next_poll = avr->cycle + poll;
      if (script) {
        if (!pump_script(avr)) break;
        if (every_poll) every_poll();
        continue;
      }
      pump_input();
      pump_output();
      if (every_poll) every_poll();
    }
    if (!script && avr->cycle >= next_check) {  /* a script runs unpaced: its host lines are at emulated times */
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
