/* bench-pkm5 firmware, plain avr-libc C for the ATmega2560 (Arduino Mega 2560) at 16 MHz.
 *
 * The line protocol of docs/protocol-pkm5.md (version 1): PC -> controller `VERB [int ...] #TAG*HH\n`,
 * controller -> PC `KIND #TAG FIELD ...*HH\n`, HH the XOR of the body bytes. Hardware (shared/reference/pkm5.md
 * §2.5): six TB6560 stepper drivers on the Mega's STEP/DIR pins (2,3) (4,5) (6,7) (8,9) (10,11) (12,13) for
 * actuators 1-6 (the dissertation's sketch, 000 App. B.2) and enable inputs on pins 22-27.
 *
 * Motion: a 10 kHz Timer1 interrupt runs a DDA. The leading axis (the longest travel) advances a 8.24 fixed-point
 * phase by its velocity every tick and steps on each overflow; the other axes follow by Bresenham, so all six start
 * and finish together. The velocity ramps trapezoidally: +dv per tick (dv = a / f_tick^2 steps/tick^2) until the
 * commanded speed, and down again over as many steps as the ramp up took (symmetric, no division in the ISR).
 * Link watchdog (in the timer interrupt): while moving, a gap of WATCHDOG_MS without a valid host command line ramps
 * the axes down at STOP_DECEL, disables the drivers and latches a WATCHDOG fault, reported on the next command.
 *
 * Build options (-D, see firmware/Makefile): ACCEL_STEPS_S2, STOP_DECEL_STEPS_S2, WATCHDOG_MS and
 * DRIVERS_ENABLED_LEVEL (the EN pin level that powers the motors; 1 = HIGH is right for the TB6560 wiring: EN- on
 * the pin, EN+ to 5 V, a pin driven LOW lights the opto-coupler and frees the motor).
 */
#include <avr/interrupt.h>
#include <avr/io.h>
#include <math.h>
#include <stdint.h>
#include <string.h>

#ifndef ACCEL_STEPS_S2
#define ACCEL_STEPS_S2 4000L        /* acceleration of the leading axis, steps/s^2 */
#endif
#ifndef STOP_DECEL_STEPS_S2
#define STOP_DECEL_STEPS_S2 25000L  /* watchdog ramp-down: 1000 steps/s to rest in 40 ms */
#endif
#ifndef WATCHDOG_MS
#define WATCHDOG_MS 150L            /* link timeout while moving, ms (+ <= 40 ms ramp-down: EN off < 250 ms); 0 = off */
#endif
#ifndef DRIVERS_ENABLED_LEVEL
#define DRIVERS_ENABLED_LEVEL 1     /* EN pin level that powers the motors (TB6560: HIGH = opto dark = enabled) */
#endif

#define DEVICE_NAME "bench-pkm5"
#define PROTOCOL_VERSION "3"  /* the highest offered; the link starts in 1 (XOR-8), PROTOCOL 2 -> CRC-16, 3 -> + MOVE dedup */
#define FIRMWARE_VERSION "3.0.0"
#define AXES 6
#define MAX_LINE 96
#define MAX_TOKENS 48
#define TICK_HZ 10000L
#define ONE_STEP (1UL << 24)        /* phase units per step */
#define MAX_SPEED_STEPS_S 1000L
#define FLOOR_SPEED_STEPS_S 20L     /* start / end speed of a ramp (a stepper starts at this speed without a ramp) */

enum { ERR_SYNTAX = 1, ERR_CHECKSUM, ERR_TOO_LONG, ERR_ARGUMENT, ERR_LIMIT, ERR_DISABLED, ERR_BUSY, ERR_STOPPED,
       ERR_WATCHDOG };
static const char *const ERROR_NAMES[] = {"", "SYNTAX", "CHECKSUM", "TOO_LONG", "ARGUMENT", "LIMIT", "DISABLED",
                                          "BUSY", "STOPPED", "WATCHDOG"};

/* Arduino Mega pin -> port bit. STEP 2,4,6,8,10,12; DIR 3,5,7,9,11,13; EN 22-27 = PA0-PA5. */
static volatile uint8_t *const STEP_PORT[AXES] = {&PORTE, &PORTG, &PORTH, &PORTH, &PORTB, &PORTB};
static const uint8_t STEP_BIT[AXES] = {_BV(4), _BV(5), _BV(3), _BV(5), _BV(4), _BV(6)};
static volatile uint8_t *const DIR_PORT[AXES] = {&PORTE, &PORTE, &PORTH, &PORTH, &PORTB, &PORTB};
static const uint8_t DIR_BIT[AXES] = {_BV(5), _BV(3), _BV(4), _BV(6), _BV(5), _BV(7)};
#define EN_MASK 0x3F
/* Set 1 for an actuator whose positive steps shorten the leg (Geometry.step_direction = -1 in motion.pkm5). */
static const uint8_t DIR_INVERTED[AXES] = {0, 0, 0, 0, 0, 0};

static const int32_t MAX_STEPS[AXES] = {10560, 10560, 10560, 10560, 21120, 21120};
static const int32_t HOME_STEPS[AXES] = {800, 800, 800, 800, 1600, 1600};

/* ---- motion state shared with the ISR ------------------------------------------------------------------- */
enum { IDLE = 0, ACCEL, CRUISE, DECEL, HALT };
static volatile uint8_t motion = IDLE;
static volatile int32_t position[AXES];
static volatile uint32_t ticks;            /* 10 kHz clock, running while a move runs (the watchdog's time) */
static int8_t direction[AXES];
static uint32_t delta[AXES], error[AXES];
static uint32_t lead_steps, done_steps, ramp_steps;
static uint32_t phase, velocity, v_max, v_floor, dv, dv_stop;
/* The link watchdog runs in the timer interrupt, not the main loop, so nothing that keeps the main loop busy (a
 * babbling line, a long reply) can keep the drives powered: the interrupt starts the ramp-down WATCHDOG_MS after the
 * last host heartbeat and drives the enable pins to the disabled level itself when the axes are at rest. */
#define WATCHDOG_TICKS (WATCHDOG_MS * (TICK_HZ / 1000))
static volatile uint32_t last_beat_tick;   /* ticks at the last valid host command line (written under cli) */
static volatile uint8_t watchdog_tripped;  /* set by the interrupt; the main loop reports it and latches the fault */

static void set_drivers(uint8_t on);

ISR(TIMER1_COMPA_vect) {
  ticks++;
  for (uint8_t i = 0; i < AXES; i++) *STEP_PORT[i] &= (uint8_t)~STEP_BIT[i];  /* pulse width: one tick */
  uint8_t state = motion;
  if (state == IDLE) { TIMSK1 = 0; return; }  /* the pulses are down: sleep until the next move (cheap to emulate) */
  phase += velocity;
  if (phase >= ONE_STEP) {
    phase -= ONE_STEP;
    for (uint8_t i = 0; i < AXES; i++) {
      error[i] += delta[i];
      if (error[i] >= lead_steps) {
        error[i] -= lead_steps;
        *STEP_PORT[i] |= STEP_BIT[i];
        position[i] += direction[i];
      }
    }
    done_steps++;
  }
  if (done_steps >= lead_steps) state = IDLE;
  else if (WATCHDOG_TICKS > 0 && state != HALT && ticks - last_beat_tick > WATCHDOG_TICKS) {
    watchdog_tripped = 1;
    state = HALT;
  }
  if (state == IDLE) {
    if (watchdog_tripped) set_drivers(0);
    motion = IDLE;
    return;
  }
  if (state == ACCEL) {
    if (lead_steps - done_steps <= done_steps) { ramp_steps = done_steps; state = DECEL; }
    else if (velocity + dv >= v_max) { velocity = v_max; ramp_steps = done_steps; state = CRUISE; }
    else velocity += dv;
  } else if (state == CRUISE) {
    if (lead_steps - done_steps <= ramp_steps) state = DECEL;
  }
  if (state == DECEL) velocity = velocity > v_floor + dv ? velocity - dv : v_floor;
  if (state == HALT) {
    if (velocity > v_floor + dv_stop) velocity -= dv_stop;
    else {
      set_drivers(0);  /* only the watchdog halts */
      motion = IDLE;
      return;
    }
  }
  motion = state;
}

static void read_positions(int32_t *out) {
  cli();
  for (uint8_t i = 0; i < AXES; i++) out[i] = position[i];
  sei();
}

static void set_drivers(uint8_t on) {  /* from the main loop and the timer interrupt: PORTA's read-modify-write atomic */
  uint8_t level_high = on ? DRIVERS_ENABLED_LEVEL : !DRIVERS_ENABLED_LEVEL;
  uint8_t sreg = SREG;
  cli();
  if (level_high) PORTA |= EN_MASK; else PORTA &= (uint8_t)~EN_MASK;
  SREG = sreg;
}

/* ---- UART0: 115200 8-N-1, interrupt-driven receive ring, polled transmit -------------------------------- */
#define RX_SIZE 256
static volatile uint8_t rx_buf[RX_SIZE];
static volatile uint8_t rx_head, rx_tail;

ISR(USART0_RX_vect) {
  uint8_t c = UDR0;
  uint8_t next = (uint8_t)(rx_head + 1);
  if (next != rx_tail) { rx_buf[rx_head] = c; rx_head = next; }
}

static void uart_put(char c) {
  while (!(UCSR0A & _BV(UDRE0))) {}
  UDR0 = (uint8_t)c;
}

static char reply[MAX_LINE + 8];
static uint8_t reply_len;
static uint8_t protocol = 1;          /* 1 = *HH XOR-8, 2 = *HHHH CRC-16-CCITT, 3 = CRC-16 + MOVE retransmission */

/* CRC-16-CCITT: polynomial 0x1021, initial 0xFFFF, no reflection, no final XOR (check("123456789") = 0x29B1). */
static uint16_t crc16(const char *bytes, uint8_t length) {
  uint16_t crc = 0xFFFF;
  for (uint8_t i = 0; i < length; i++) {
    crc ^= (uint16_t)((uint8_t)bytes[i]) << 8;
    for (uint8_t bit = 0; bit < 8; bit++) crc = (crc & 0x8000) ? (uint16_t)((crc << 1) ^ 0x1021) : (uint16_t)(crc << 1);
  }
  return crc;
}

static void put_text(const char *text) {
  while (*text && reply_len < MAX_LINE) reply[reply_len++] = *text++;
}

static void put_number(int32_t value, uint8_t leading_space) {
  char digits[12];
  uint8_t n = 0;
  uint32_t magnitude = value < 0 ? (uint32_t)(-(value + 1)) + 1 : (uint32_t)value;
  do { digits[n++] = (char)('0' + magnitude % 10); magnitude /= 10; } while (magnitude);
  if (value < 0) digits[n++] = '-';
  if (leading_space && reply_len < MAX_LINE) reply[reply_len++] = ' ';
  while (n && reply_len < MAX_LINE) reply[reply_len++] = digits[--n];
}

static void put_long(int32_t value) { put_number(value, 1); }

static void reply_start(const char *kind, int32_t tag) {
  reply_len = 0;
  put_text(kind);
  put_text(" #");
  put_number(tag, 0);
}

static void reply_send(void) {
  static const char HEX[] = "0123456789ABCDEF";
  uint16_t check;
  uint8_t digits;
  if (protocol >= 2) {
    check = crc16(reply, reply_len);
    digits = 4;
  } else {
    check = 0;
    for (uint8_t i = 0; i < reply_len; i++) check ^= (uint8_t)reply[i];
    digits = 2;
  }
  reply[reply_len++] = '*';
  while (digits) reply[reply_len++] = HEX[(check >> (4 * --digits)) & 0x0F];
  reply[reply_len++] = '\n';
  for (uint8_t i = 0; i < reply_len; i++) uart_put(reply[i]);
}

static void put_positions(void) {
  int32_t where[AXES];
  read_positions(where);
  for (uint8_t i = 0; i < AXES; i++) put_long(where[i]);
}

static void send_error(int32_t tag, uint8_t code, uint8_t with_positions) {
  reply_start("ERR", tag);
  put_long(code);
  put_text(" ");
  put_text(ERROR_NAMES[code]);
  if (with_positions) put_positions();
  reply_send();
}

/* ---- commands ------------------------------------------------------------------------------------------- */
static uint8_t enabled;
static int32_t move_tag;
static uint8_t move_active;          /* a MOVE whose DONE / ERR has not been sent yet */
static uint8_t fault_latched;        /* reported on the next valid command */
/* Version 3: the last accepted MOVE, so that a retransmission (the same tag) is answered, never executed again */
static int32_t last_move_tag = -1;
static int32_t last_move_duration;
static uint8_t last_move_end;        /* 0 while it runs, else ERR_STOPPED, ERR_WATCHDOG or 0xFF (DONE) */
static int32_t last_move_where[AXES];
#define END_DONE 0xFF

static int hex_value(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

static uint8_t all_digits(const char *s, uint8_t max_digits) {
  uint8_t n = 0;
  for (; *s; s++, n++) if (*s < '0' || *s > '9') return 0;
  return n >= 1 && n <= max_digits;
}

/* A decimal integer: optional '-', 1-10 digits (int64: 10 digits do not fit in 32 bits). */
static uint8_t parse_int(const char *s, int64_t *value) {
  uint8_t negative = *s == '-';
  if (negative) s++;
  if (!all_digits(s, 10)) return 0;
  int64_t v = 0;
  for (; *s; s++) v = v * 10 + (*s - '0');
  *value = negative ? -v : v;
  return 1;
}

static uint8_t within_limits(const int64_t *steps) {
  for (uint8_t i = 0; i < AXES; i++) if (steps[i] < 0 || steps[i] > MAX_STEPS[i]) return 0;
  return 1;
}

static uint32_t speed_to_velocity(uint32_t steps_s) {  /* steps/s -> phase units per tick, rounded */
  return (uint32_t)((((uint64_t)steps_s << 24) + TICK_HZ / 2) / TICK_HZ);
}

static uint32_t accel_to_dv(uint32_t steps_s2) {       /* steps/s^2 -> phase units per tick^2, rounded */
  return (uint32_t)((((uint64_t)steps_s2 << 24) + TICK_HZ * TICK_HZ / 2) / (TICK_HZ * TICK_HZ));
}

/* Announced duration, ms: trapezoid n/v + v/a, or triangle 2 sqrt(n/a) when the speed is never reached. */
static int32_t move_duration_ms(uint32_t n, uint32_t v) {
  if ((uint64_t)v * v <= (uint64_t)n * ACCEL_STEPS_S2)
    return (int32_t)((n * 1000UL + v / 2) / v + (v * 1000UL + ACCEL_STEPS_S2 / 2) / ACCEL_STEPS_S2);
  return (int32_t)(2000.0 * sqrt((double)n / ACCEL_STEPS_S2) + 0.5);
}

static void start_move(int32_t tag, const int64_t *targets, uint32_t speed) {
  int32_t where[AXES];
  read_positions(where);
  uint32_t longest = 0;
  for (uint8_t i = 0; i < AXES; i++) {
    int32_t d = (int32_t)targets[i] - where[i];
    direction[i] = d < 0 ? -1 : 1;
    delta[i] = (uint32_t)(d < 0 ? -d : d);
    if (delta[i] > longest) longest = delta[i];
    uint8_t high = (d < 0) ^ DIR_INVERTED[i];
    if (high) *DIR_PORT[i] |= DIR_BIT[i]; else *DIR_PORT[i] &= (uint8_t)~DIR_BIT[i];
  }
  last_move_tag = tag;
  last_move_duration = longest == 0 ? 0 : move_duration_ms(longest, speed);
  last_move_end = 0;
  reply_start("OK", tag);
  put_text(" MOVE");
  put_long(last_move_duration);
  reply_send();
  if (longest == 0) {
    last_move_end = END_DONE;
    read_positions(last_move_where);
    reply_start("DONE", tag);
    put_positions();
    reply_send();
    return;
  }
  for (uint8_t i = 0; i < AXES; i++) error[i] = longest / 2;
  lead_steps = longest;
  done_steps = 0;
  ramp_steps = 0;
  phase = 0;
  v_max = speed_to_velocity(speed);
  v_floor = speed_to_velocity(speed < FLOOR_SPEED_STEPS_S ? speed : FLOOR_SPEED_STEPS_S);
  dv = accel_to_dv(ACCEL_STEPS_S2);
  dv_stop = accel_to_dv(STOP_DECEL_STEPS_S2);
  velocity = v_floor;
  move_tag = tag;
  move_active = 1;
  cli();
  motion = v_floor >= v_max ? CRUISE : ACCEL;
  TCNT1 = 0;
  TIFR1 = _BV(OCF1A);
  TIMSK1 = _BV(OCIE1A);
  sei();
}

static void halt_now(void) {
  cli();
  motion = IDLE;
  sei();
}

/* The running move is over (the axes are at rest): report it. A watchdog trip wins over everything else, a STOP
 * that arrives during its ramp-down included: the drives go to the disabled level and the fault is latched. */
static void finish_move(uint8_t stopped) {
  move_active = 0;
  read_positions(last_move_where);
  last_move_end = watchdog_tripped ? ERR_WATCHDOG : stopped ? ERR_STOPPED : END_DONE;
  if (watchdog_tripped) {
    watchdog_tripped = 0;
    enabled = 0;
    set_drivers(0);
    fault_latched = 1;
    send_error(move_tag, ERR_WATCHDOG, 1);
  } else if (stopped) {
    send_error(move_tag, ERR_STOPPED, 1);
  } else {
    reply_start("DONE", move_tag);
    put_positions();
    reply_send();
  }
}

/* A host heartbeat: a valid line whose verb only a host sends (a reply echoed back to us is no heartbeat). */
static const char *const HOST_VERBS[] = {"ID", "POS", "STOP", "ENABLE", "DISABLE", "SETPOS", "MOVE", "PROTOCOL"};

static void heartbeat_if_host(const char *verb) {
  for (uint8_t i = 0; i < sizeof HOST_VERBS / sizeof HOST_VERBS[0]; i++) {
    if (strcmp(verb, HOST_VERBS[i]) == 0) {
      cli();
      last_beat_tick = ticks;
      sei();
      return;
    }
  }
}

/* A retransmitted MOVE (version 3, the tag of the last accepted one): its OK again and, once it has ended, its end. */
static void replay_move(void) {
  reply_start("OK", last_move_tag);
  put_text(" MOVE");
  put_long(last_move_duration);
  reply_send();
  if (!last_move_end) return;
  if (last_move_end == END_DONE) reply_start("DONE", last_move_tag);
  else {
    reply_start("ERR", last_move_tag);
    put_long(last_move_end);
    put_text(" ");
    put_text(ERROR_NAMES[last_move_end]);
  }
  for (uint8_t i = 0; i < AXES; i++) put_long(last_move_where[i]);
  reply_send();
}

static void execute(int32_t tag, const char *verb, uint8_t argc, const int64_t *args) {
  uint8_t busy = move_active;
  if (strcmp(verb, "PROTOCOL") == 0 && argc == 1) {
    /* no way back to XOR-8 once CRC-16 is on: a damaged CRC line must never downgrade the link */
    if (args[0] < 1 || args[0] > 3 || args[0] < protocol) { send_error(tag, ERR_ARGUMENT, 0); return; }
    reply_start("OK", tag);
    put_text(" PROTOCOL");
    put_long((int32_t)args[0]);
    reply_send();                       /* in the framing the command came in */
    protocol = (uint8_t)args[0];
  } else if (strcmp(verb, "ID") == 0 && argc == 0) {
    reply_start("OK", tag);
    put_text(" ID " DEVICE_NAME " " PROTOCOL_VERSION " " FIRMWARE_VERSION);
    reply_send();
  } else if (strcmp(verb, "POS") == 0 && argc == 0) {
    reply_start("OK", tag);
    put_text(" POS");
    put_positions();
    put_text(busy ? " MOVING" : (enabled ? " IDLE" : " DISABLED"));
    reply_send();
  } else if (strcmp(verb, "STOP") == 0 && argc == 0) {
    if (busy) {
      halt_now();
      finish_move(1);
    }
    reply_start("OK", tag);
    put_text(" STOP");
    put_positions();
    reply_send();
  } else if ((strcmp(verb, "ENABLE") == 0 || strcmp(verb, "DISABLE") == 0) && argc == 0) {
    if (busy) { send_error(tag, ERR_BUSY, 0); return; }
    enabled = verb[0] == 'E';
    set_drivers(enabled);
    reply_start("OK", tag);
    put_text(" ");
    put_text(verb);
    reply_send();
  } else if (strcmp(verb, "SETPOS") == 0 && argc == AXES) {
    if (busy) send_error(tag, ERR_BUSY, 0);
    else if (!within_limits(args)) send_error(tag, ERR_LIMIT, 0);
    else {
      cli();
      for (uint8_t i = 0; i < AXES; i++) position[i] = (int32_t)args[i];
      sei();
      reply_start("OK", tag);
      put_text(" SETPOS");
      reply_send();
    }
  } else if (strcmp(verb, "MOVE") == 0 && argc == AXES + 1) {
    int64_t speed = args[AXES];
    if (protocol >= 3 && tag == last_move_tag) replay_move();
    else if (busy) send_error(tag, ERR_BUSY, 0);
    else if (speed < 1 || speed > MAX_SPEED_STEPS_S) send_error(tag, ERR_ARGUMENT, 0);
    else if (!within_limits(args)) send_error(tag, ERR_LIMIT, 0);
    else if (!enabled) send_error(tag, ERR_DISABLED, 0);
    else start_move(tag, args, (uint32_t)speed);
  } else {
    send_error(tag, ERR_SYNTAX, 0);
  }
}

/* Whether line[0..length) ends in a valid *HH (version 1) or *HHHH (version 2); *body = the body length. */
static uint8_t frame_ok(const char *line, uint8_t length, uint8_t version, uint8_t *body) {
  uint8_t digits = version >= 2 ? 4 : 2;
  if (length < digits + 1 || line[length - digits - 1] != '*') return 0;
  uint16_t claimed = 0;
  for (uint8_t i = length - digits; i < length; i++) {
    int v = hex_value(line[i]);
    if (v < 0) return 0;
    claimed = (uint16_t)(claimed * 16 + v);
  }
  *body = length - digits - 1;
  uint16_t actual = 0;
  if (version >= 2) actual = crc16(line, *body);
  else for (uint8_t i = 0; i < *body; i++) actual ^= (uint8_t)line[i];
  return claimed == actual;
}

/* One received line (terminator removed). Order of checks, as bench/robots/pkm5_wire.py: length (done by the
 * reader), one trailing '\r' dropped, empty -> ignored, '*HH' and checksum -> CHECKSUM #0, then the tokens:
 * the tag is trusted when exactly one token starts with '#' and it is '#' + 1-9 digits; every later refusal
 * carries that tag (else 0). */
static void handle_line(char *line, uint8_t length) {
  if (length > 0 && line[length - 1] == '\r') line[--length] = '\0';
  if (length == 0) return;
  uint8_t body;
  if (!frame_ok(line, length, protocol, &body)) {
    /* version 2 is kept until reset: a CRC line that lost two characters reads as an XOR line 1 time in 256 */
    send_error(0, ERR_CHECKSUM, 0);
    return;
  }
  line[body] = '\0';
  char *tokens[MAX_TOKENS];
  uint8_t count = 0, tag_tokens = 0, printable = 1;
  int32_t tag = 0;
  for (uint8_t i = 0; i < body; i++) if ((uint8_t)line[i] < 0x20 || (uint8_t)line[i] > 0x7E) printable = 0;
  for (char *p = line; *p;) {
    while (*p == ' ') *p++ = '\0';
    if (!*p) break;
    if (*p == '#') {
      tag_tokens++;
      char *digits = p + 1;
      while (*p && *p != ' ') p++;
      char saved = *p;
      *p = '\0';
      if (all_digits(digits, 9)) {
        int32_t v = 0;
        for (const char *d = digits; *d; d++) v = v * 10 + (*d - '0');
        tag = v;
      } else {
        tag_tokens = 100;  /* a malformed tag: untrusted */
      }
      *p = saved;
      continue;
    }
    if (count < MAX_TOKENS) tokens[count++] = p;
    while (*p && *p != ' ') p++;
  }
  if (tag_tokens != 1) { send_error(0, ERR_SYNTAX, 0); return; }
  if (count) heartbeat_if_host(tokens[0]);
  if (fault_latched) {
    fault_latched = 0;
    send_error(tag, ERR_WATCHDOG, 1);
    return;
  }
  if (!printable || count == 0 || count > AXES + 2) { send_error(tag, ERR_SYNTAX, 0); return; }
  int64_t args[AXES + 1];
  uint8_t argc = count - 1;
  for (uint8_t i = 0; i < argc; i++) {
    if (!parse_int(tokens[i + 1], &args[i])) { send_error(tag, ERR_SYNTAX, 0); return; }
  }
  execute(tag, tokens[0], argc, args);
}

static char line_buf[MAX_LINE + 1];
static uint8_t line_len, line_overflow;

static void poll_uart(void) {
  while (rx_tail != rx_head) {
    char c = (char)rx_buf[rx_tail];
    rx_tail = (uint8_t)(rx_tail + 1);
    if (c == '\n') {
      if (line_overflow) send_error(0, ERR_TOO_LONG, 0);
      else { line_buf[line_len] = '\0'; handle_line(line_buf, line_len); }
      line_len = 0;
      line_overflow = 0;
      return;  /* one line per pass: the main loop reports the motion between lines, whatever the babble */
    } else if (line_len >= MAX_LINE) {
      line_overflow = 1;
    } else {
      line_buf[line_len++] = c;
    }
  }
}

static void poll_motion(void) {
  if (move_active && motion == IDLE) finish_move(0);
}

int main(void) {
  for (uint8_t i = 0; i < AXES; i++) {
    position[i] = HOME_STEPS[i];
    *(STEP_PORT[i] - 1) |= STEP_BIT[i];  /* DDRx sits one address below PORTx */
    *(DIR_PORT[i] - 1) |= DIR_BIT[i];
  }
  set_drivers(0);
  DDRA |= EN_MASK;
  UBRR0 = 16;                            /* 115200 baud at 16 MHz with U2X: 2.1 % error, as the Arduino core */
  UCSR0A = _BV(U2X0);
  UCSR0B = _BV(RXEN0) | _BV(TXEN0) | _BV(RXCIE0);
  UCSR0C = _BV(UCSZ01) | _BV(UCSZ00);
  OCR1A = F_CPU / TICK_HZ - 1;
  TCCR1A = 0;
  TCCR1B = _BV(WGM12) | _BV(CS10);       /* CTC, no prescaler */
  sei();
  reply_start("BOOT", 0);
  put_text(" " DEVICE_NAME " " PROTOCOL_VERSION " " FIRMWARE_VERSION);
  reply_send();
  for (;;) {  /* a polling loop: the ISRs do the timing (idle sleep would save nothing on a USB-powered board) */
    poll_uart();
    poll_motion();
  }
}
