/* bench-delta4 firmware, plain avr-libc C for the ATmega128 at 16 MHz (the delta robot's controller of seed 003,
 * shared/reference/delta4-lasergrid.md §5.1: one ATmega128, four servo PWM outputs, the laser-grid screens, RS-232).
 *
 * Protocol (docs/protocol-delta4.md, reference §5.4-5.7), byte-oriented, no checksum (the document has none):
 *   PC -> MCU  `E` start control and sensor reporting, `G` stop, `P`/`Q`/`R`/`S` + 1-3 digits + `X` reference
 *              0-255 of servo 1-4 (stored while stopped, applied at `E`), `z` acknowledgement, `A` pot query (this
 *              project's extension), `C` capability query and `F` + servo digit 1-4 + 1-5 digits + `X` fine
 *              reference in 0.01 deg of theta_R (this project's second extension, "Fine servo references");
 *              anything else is ignored and a malformed message is discarded, exactly as `bench sim delta4` does.
 *   MCU -> PC  `z` once all servos have reached their references after the last command, one sensor report
 *              per 80 ms frame while started: `H%03dX` per lit sensor of the horizontal screen (or `h`), then
 *              `V%03dX` per lit sensor of the vertical screen (or `v`), and after each `A` (started or not) the four
 *              pot ADC counts `p%03dXq%03dXr%03dXs%03dX`, after each `C` `c%05dX`, the angle step a fine reference
 *              positions on in 1e-5 deg (one PWM tick: 180 deg / PULSE_SPAN_TICKS, 01125 at the 2 ms refresh),
 *              never inside a report.
 *
 * Servo PWM (reference §5.2, document §7.3.6): Timer1 and Timer3 in fast PWM mode 14 (TOP = ICR), no prescaler
 * (0.0625 us per tick) for the documented 2 ms (500 Hz) refresh; OC1A PB5, OC1B PB6, OC3A PE3, OC3B PE4 drive
 * servos 1-4. SERVO_PERIOD_US=20000 builds a 50 Hz refresh (prescaler 8, 0.5 us per tick) for standard servos.
 * Pulse width [choice, reference §1.8: JR-591 neutral about 1.5 ms, typically 1-2 ms]:
 *     pulse_us = SERVO_PULSE_AT_0_DEG_US + theta_R * (SERVO_PULSE_AT_180_DEG_US - SERVO_PULSE_AT_0_DEG_US) / 180
 * with theta_R the servo angle the byte means under the build's mapping (reference §5.8, bench.robots.delta4_wire):
 *     legacy_vb   theta_R = byte * 190 / 255                       (MAPPING_CALIBRATED=0, the default)
 *     calibrated  theta_R = 30 + byte * 140 / 255  (direction +1)  (MAPPING_CALIBRATED=1; -1: 170 - byte*140/255)
 * clamped to the calibrated mechanical stops [30, 170] deg (the Perspex tool, §6.5), rounded half up to a tick.
 * A fine reference `F<n><value>X` gives theta_R = value / 100 deg directly (no byte mapping; same clamp and rounding:
 *     pulse_ticks = round_half_up(PULSE_0_TICKS + value * PULSE_SPAN_TICKS / 18000)), 66x finer than a legacy byte.
 * The pulses start at the first `E` (before it the lines stay low: no mechanical control) from the home pose
 * (0, 0, -150) mm, theta_R = 71.657 deg on every servo (motion.delta4 IK).
 *
 * Motion: every PWM period the commanded pulse of each servo moves towards its reference by at most
 * SERVO_SLEW_DEG_S (the slew limit; default 286 deg/s, the JR-591's rated 60 deg / 0.21 s, §5.3); `z` follows once
 * all four have sat on their references for SETTLE_MS (10 ticks of 2 ms, reference §5.7 item 7). `G` freezes the
 * pulses where they are (the servos hold the pose: an RC servo without pulses goes limp and the robot would drop).
 * Link watchdog: while a servo is still moving, a gap of WATCHDOG_MS with no received byte freezes every servo where
 * it is and drops the pending `z` (the host sees its move unconfirmed). Any byte counts as a heartbeat (`z` is the
 * harmless one). The default exceeds the longest move (190 deg at the slew limit), so a host that only sends its
 * moves never trips it.
 *
 * Laser grid (reference §4.2, §4.9, §5.2): every 80 ms frame both laser sets are switched on (PC4 horizontal, PC5
 * vertical), after 1 ms the two 256-bit chains of 74LS166 are cleared (CLEAR PC3 low) and parallel-loaded
 * (SHIFT/LOAD PC1 low, CLOCK PC0 rising, CLOCK INHIBIT PC2 low), the lasers go off, and 256 clocks shift the bits
 * out of QH (horizontal PA0, vertical PA1): the index of a set bit is the number of clocks before it (0-based).
 * Pot ADCs (reference §5.1, §5.2; document §5.4, §7.3.5): four TLC548 on the servo pot wipers, read together every
 * PWM period (2 ms, as documented): CS (PA2) low, 8 I/O CLOCK (PA3) pulses, each bit read MSB first from the four
 * DATA OUT lines (PA4-PA7, servos 1-4) before its rising edge, CS high again (the chips convert while it is high).
 * The document sends the readings nowhere (§7.3.4); this firmware answers the query `A`, which no documented host
 * sends, with `p%03dX q%03dX r%03dX s%03dX`, the latest counts of servos 1-4 (docs/protocol-delta4.md). `z` still
 * reports the commanded pulses, not the measured angles (the command and ADC scales disagree, reference §5.8).
 *
 * Build options (-D, see firmware/Makefile): SERVO_PERIOD_US, SERVO_SLEW_DEG_S, WATCHDOG_MS, MAPPING_CALIBRATED,
 * CALIBRATED_DIRECTION, BAUD.
 */
#include <avr/interrupt.h>
#include <avr/io.h>
#include <avr/sleep.h>
#include <stdint.h>
#include <util/delay.h>

#ifndef SERVO_PERIOD_US
#define SERVO_PERIOD_US 2000L          /* PWM refresh period, us (document §7.3.6: 2 ms) */
#endif
#ifndef SERVO_SLEW_DEG_S
#define SERVO_SLEW_DEG_S 286L          /* slew limit of the commanded angle, deg/s */
#endif
#ifndef WATCHDOG_MS
#define WATCHDOG_MS 1000L              /* link timeout while a servo moves, ms (0 = off) */
#endif
#ifndef MAPPING_CALIBRATED
#define MAPPING_CALIBRATED 0           /* 0: legacy_vb byte mapping, 1: calibrated */
#endif
#ifndef CALIBRATED_DIRECTION
#define CALIBRATED_DIRECTION 1         /* calibrated mapping: +1 byte 0 at the low stop, -1 at the high stop */
#endif
#ifndef BAUD
#define BAUD 9600L                     /* not stated by the document; bench.robots.delta4.DEFAULT_BAUDRATE */
#endif

#define SERVOS 4
#define SERVO_PULSE_AT_0_DEG_US 1000L
#define SERVO_PULSE_AT_180_DEG_US 2000L
#define SERVO_STOP_LOW_MDEG 30000L     /* calibrated stops, millidegrees of theta_R */
#define SERVO_STOP_HIGH_MDEG 170000L
#define LEGACY_SPAN_MDEG 190000L       /* legacy_vb: byte 255 <-> 190 deg (VB factor 255/190) */
#define HOME_BYTE (MAPPING_CALIBRATED ? (CALIBRATED_DIRECTION > 0 ? 76 : 179) : 96)  /* 71.657 deg */
#define SETTLE_MS 20L
#define FRAME_MS 80L                   /* sensor cycle, §5.5 */
#define LASER_ON_US 1000               /* laser pulse before the load, §5.5 */
#define SENSORS 256

#define TIMER_PRESCALE (SERVO_PERIOD_US * 16L > 65536L ? 8L : 1L)
#define TICKS_PER_US (16L / TIMER_PRESCALE)
#define PERIOD_TICKS (SERVO_PERIOD_US * TICKS_PER_US)
#define PULSE_0_TICKS (SERVO_PULSE_AT_0_DEG_US * TICKS_PER_US)
#define PULSE_SPAN_TICKS ((SERVO_PULSE_AT_180_DEG_US - SERVO_PULSE_AT_0_DEG_US) * TICKS_PER_US)
/* setpoints are in 1/256 timer tick; the slew step per PWM period in the same unit */
#define SLEW_Q8_PER_PERIOD ((uint32_t)((long long)SERVO_SLEW_DEG_S * PULSE_SPAN_TICKS * 256LL * SERVO_PERIOD_US \
                                       / (180LL * 1000000LL)))
/* the fine reference's positioning step, 1e-5 deg: one timer tick of the pulse span */
#define FINE_STEP_UNITS ((18000000L + PULSE_SPAN_TICKS / 2) / PULSE_SPAN_TICKS)
#define FINE_MAX_CDEG 18000L
#define PERIODS(ms) (((ms) * 1000L + SERVO_PERIOD_US - 1) / SERVO_PERIOD_US)

#if PERIOD_TICKS > 65536L || SERVO_PERIOD_US * 180L <= SERVO_PULSE_AT_0_DEG_US * 180L \
    + (SERVO_PULSE_AT_180_DEG_US - SERVO_PULSE_AT_0_DEG_US) * (SERVO_STOP_HIGH_MDEG / 1000L)
#error "SERVO_PERIOD_US: the period must hold the widest pulse (theta_R = 170 deg) and fit a 16-bit timer"
#endif

/* grid control lines on PORTC, data lines on PINA */
#define GRID_CLOCK _BV(0)
#define GRID_SHIFT_LOAD _BV(1)
#define GRID_INHIBIT _BV(2)
#define GRID_CLEAR _BV(3)
#define LASER_H _BV(4)
#define LASER_V _BV(5)
/* pot ADCs (TLC548) on PORTA: chip select and I/O clock shared by the four, DATA OUT of servo i on PA(4 + i) */
#define ADC_CS _BV(2)
#define ADC_CLOCK _BV(3)
#define ADC_DATA_FIRST_BIT 4
#define ADC_SETUP_US 2.0               /* CS low to the first clock: TLC548 tsu(CS) >= 1.425 us */
#define ADC_HALF_CLOCK_US 1.0          /* I/O CLOCK high and low times: >= 404 ns, data valid 400 ns after the fall */

/* ---- state shared with the ISRs -------------------------------------------------------------------------- */
static volatile uint32_t ticks;                /* PWM periods since boot */
static volatile uint32_t last_rx_tick;
static volatile uint8_t started, pulses_on, z_pending, z_due, frame_due;
static volatile uint8_t settled_periods, frame_periods;
static volatile uint32_t setpoint_q8[SERVOS], target_q8[SERVOS];
static volatile uint16_t watchdog_stops;
static volatile uint8_t pot_counts[SERVOS];    /* the latest TLC548 readings, servos 1-4 */
/* queries not yet answered, counted: two `A` read in one pass of service_rx (the main loop busy with a report
 * while both arrived) get two answers, as the simulator gives */
static volatile uint8_t pots_asked, capability_asked;

static volatile uint8_t rx_buf[64], rx_head, rx_tail;
static volatile uint8_t tx_buf[64], tx_head, tx_tail;

/* Pulse of `servo` = `value` + 1 ticks from the next period on (OCRnx is double-buffered to BOTTOM). */
static inline void set_compare(uint8_t servo, uint16_t value) {
  switch (servo) {
    case 0: OCR1A = value; break;
    case 1: OCR1B = value; break;
    case 2: OCR3A = value; break;
    default: OCR3B = value; break;
  }
}

/* simavr 1.6 (Debian) takes a new OCR in fast PWM only when the timer is reconfigured: stopping and restarting the
 * clock right after TOP does that. On silicon it holds the counter for two cycles, so a period in which a setpoint
 * changed lasts 2 ticks (0.125 us) longer; periods at rest are untouched. */
static inline void latch_compares(void) {
  uint8_t b1 = TCCR1B, b3 = TCCR3B;
  TCCR1B = b1 & (uint8_t)~(_BV(CS12) | _BV(CS11) | _BV(CS10));
  TCCR3B = b3 & (uint8_t)~(_BV(CS32) | _BV(CS31) | _BV(CS30));
  TCCR1B = b1;
  TCCR3B = b3;
}

/* One simultaneous read of the four TLC548 (document §7.3.5): 8 bits MSB first, each read before its clock's
 * rising edge (a falling edge puts the next bit on DATA OUT); CS high again starts the chips' next conversion
 * (17 us), long done by the next read 2 ms later. About 22 us. */
static inline void read_pots(void) {
  uint8_t sample[8];  /* PINA before each rising edge; unpacked after the read so that the clock runs fast */
  PORTA &= (uint8_t)~ADC_CS;
  _delay_us(ADC_SETUP_US);
  for (uint8_t bit = 0; bit < 8; bit++) {
    sample[bit] = PINA;
    PORTA |= ADC_CLOCK;
    _delay_us(ADC_HALF_CLOCK_US);
    PORTA &= (uint8_t)~ADC_CLOCK;
    _delay_us(ADC_HALF_CLOCK_US);
  }
  PORTA |= ADC_CS;
  for (uint8_t i = 0; i < SERVOS; i++) {
    uint8_t value = 0, mask = (uint8_t)_BV(ADC_DATA_FIRST_BIT + i);
    for (uint8_t bit = 0; bit < 8; bit++) value = (uint8_t)(value << 1 | ((sample[bit] & mask) != 0));
    pot_counts[i] = value;
  }
}

ISR(TIMER1_OVF_vect) {  /* once per PWM period, at TOP */
  static uint16_t next_compare[SERVOS];
  static uint8_t compares_changed;
  if (compares_changed) {  /* first thing after TOP: last period's slew step, for the period just begun */
    for (uint8_t i = 0; i < SERVOS; i++) set_compare(i, next_compare[i]);
    latch_compares();
    compares_changed = 0;
  }
  ticks++;
  read_pots();  /* every period, started or not: the pots show where the arms are even before `E` */
  if (!started) return;
  uint8_t moving = 0;
  for (uint8_t i = 0; i < SERVOS; i++) {
    uint32_t now = setpoint_q8[i], goal = target_q8[i];
    if (now != goal) {
      if (goal > now) now = goal - now > SLEW_Q8_PER_PERIOD ? now + SLEW_Q8_PER_PERIOD : goal;
      else now = now - goal > SLEW_Q8_PER_PERIOD ? now - SLEW_Q8_PER_PERIOD : goal;
      setpoint_q8[i] = now;
      moving = 1;
    }
    next_compare[i] = (uint16_t)((now >> 8) - 1);  /* fast PWM: high for OCR + 1 ticks */
  }
  compares_changed = moving;
  if (moving) {
    settled_periods = 0;
    if (WATCHDOG_MS && ticks - last_rx_tick > PERIODS(WATCHDOG_MS)) {  /* the host is gone: hold here */
      for (uint8_t i = 0; i < SERVOS; i++) target_q8[i] = setpoint_q8[i];
      z_pending = 0;
      watchdog_stops++;
    }
  } else if (z_pending && ++settled_periods >= PERIODS(SETTLE_MS)) {
    z_pending = 0;
    z_due = 1;
  }
  if (++frame_periods >= PERIODS(FRAME_MS)) {
    frame_periods = 0;
    frame_due = 1;
  }
}

ISR(USART0_RX_vect) {
  uint8_t byte = UDR0, next = (uint8_t)((rx_head + 1) % sizeof rx_buf);
  last_rx_tick = ticks;
  if (next != rx_tail) {
    rx_buf[rx_head] = byte;
    rx_head = next;
  }
}

ISR(USART0_UDRE_vect) {
  if (tx_tail == tx_head) {
    UCSR0B &= (uint8_t)~_BV(UDRIE0);
    return;
  }
  UDR0 = tx_buf[tx_tail];
  tx_tail = (uint8_t)((tx_tail + 1) % sizeof tx_buf);
}

static void service_rx(void);

static void put(uint8_t byte) {
  uint8_t next = (uint8_t)((tx_head + 1) % sizeof tx_buf);
  while (next == tx_tail) service_rx();  /* full: wait for the UART, handling commands meanwhile (a long report) */
  tx_buf[tx_head] = byte;
  tx_head = next;
  UCSR0B |= _BV(UDRIE0);
}

/* ---- servo references -------------------------------------------------------------------------------------- */
/* The pulse of reference byte `value`, in 1/256 timer tick (formula in the header). */
static uint32_t pulse_q8(uint8_t value) {
  int32_t mdeg255;  /* theta_R in millidegrees times 255: exact for every byte */
  if (MAPPING_CALIBRATED) {
    int32_t span = (SERVO_STOP_HIGH_MDEG - SERVO_STOP_LOW_MDEG) * (int32_t)value;
    mdeg255 = CALIBRATED_DIRECTION > 0 ? SERVO_STOP_LOW_MDEG * 255L + span : SERVO_STOP_HIGH_MDEG * 255L - span;
  } else {
    mdeg255 = LEGACY_SPAN_MDEG * (int32_t)value;
  }
  if (mdeg255 < SERVO_STOP_LOW_MDEG * 255L) mdeg255 = SERVO_STOP_LOW_MDEG * 255L;
  if (mdeg255 > SERVO_STOP_HIGH_MDEG * 255L) mdeg255 = SERVO_STOP_HIGH_MDEG * 255L;
  const uint64_t denominator = 180000ULL * 255ULL;
  uint64_t ticks_pulse = ((uint64_t)PULSE_0_TICKS * denominator + (uint64_t)mdeg255 * PULSE_SPAN_TICKS
                          + denominator / 2) / denominator;
  return (uint32_t)ticks_pulse << 8;
}

/* The pulse of fine reference `cdeg` (theta_R in 0.01 deg), in 1/256 timer tick: clamped to the stops, rounded
 * half up to a tick (formula in the header). */
static uint32_t fine_pulse_q8(uint16_t cdeg) {
  uint32_t clamped = cdeg < SERVO_STOP_LOW_MDEG / 10 ? SERVO_STOP_LOW_MDEG / 10
                     : cdeg > SERVO_STOP_HIGH_MDEG / 10 ? SERVO_STOP_HIGH_MDEG / 10 : cdeg;
  uint64_t ticks_pulse = ((uint64_t)PULSE_0_TICKS * FINE_MAX_CDEG + (uint64_t)clamped * PULSE_SPAN_TICKS
                          + FINE_MAX_CDEG / 2) / FINE_MAX_CDEG;
  return (uint32_t)ticks_pulse << 8;
}

static uint8_t stored_while_stopped;

static void set_reference(uint8_t servo, uint32_t goal) {
  cli();
  target_q8[servo] = goal;
  if (started) {
    z_pending = 1;
    settled_periods = 0;
  }
  sei();
  stored_while_stopped = !started;
}

static void start(void) {
  if (started) return;
  if (!pulses_on) {  /* first start: connect the compare outputs (non-inverting) */
    TCCR1A |= _BV(COM1A1) | _BV(COM1B1);
    TCCR3A |= _BV(COM3A1) | _BV(COM3B1);
    pulses_on = 1;
  }
  cli();
  if (stored_while_stopped) {  /* 'z' follows servo commands only (§5.7 items 7 and 10) */
    z_pending = 1;
    settled_periods = 0;
  }
  frame_periods = 0;
  frame_due = 1;  /* the first report at once */
  last_rx_tick = ticks;
  started = 1;
  sei();
  stored_while_stopped = 0;
}

static void stop(void) {
  cli();
  started = 0;
  frame_due = 0;
  sei();
}

/* ---- protocol: the byte state machine of bench.simulators.delta4.Delta4SimDevice._byte --------------------- */
static uint8_t letter, digits_count, fine_servo;
static uint32_t value_so_far;

static void on_byte(uint8_t byte) {
  if (letter) {
    uint8_t fine = letter == 'F';  /* F, the servo digit, then up to five digits of 0.01 deg */
    if (byte >= '0' && byte <= '9' && digits_count < (fine ? 6 : 3)) {
      if (fine && digits_count == 0) fine_servo = (uint8_t)(byte - '0');
      else value_so_far = value_so_far * 10 + (uint32_t)(byte - '0');
      digits_count++;
      return;
    }
    uint8_t servo = (uint8_t)(letter - 'P');
    letter = 0;
    if (byte == 'X' && fine && digits_count >= 2 && fine_servo >= 1 && fine_servo <= 4
        && value_so_far <= FINE_MAX_CDEG) {
      set_reference((uint8_t)(fine_servo - 1), fine_pulse_q8((uint16_t)value_so_far));
      return;
    }
    if (byte == 'X' && !fine && digits_count && value_so_far <= 255) {
      set_reference(servo, pulse_q8((uint8_t)value_so_far));
      return;
    }
    if ((byte >= '0' && byte <= '9') || byte == 'X') return;  /* malformed message discarded with this byte */
  }
  if ((byte >= 'P' && byte <= 'S') || byte == 'F') {
    letter = byte;
    digits_count = 0;
    value_so_far = 0;
  } else if (byte == 'E') {
    start();
  } else if (byte == 'G') {
    stop();
  } else if (byte == 'A') {
    if (pots_asked < 255) pots_asked++;  /* answered from the main loop, after any report under way */
  } else if (byte == 'C') {
    if (capability_asked < 255) capability_asked++;  /* likewise */
  }  /* 'z' (acknowledgement), 'T' (undocumented) and anything else: ignored */
}

/* ---- laser grid ------------------------------------------------------------------------------------------ */
static uint8_t hits[2][SENSORS / 8];

static void scan_screens(void) {
  PORTC |= LASER_H | LASER_V;
  _delay_us(LASER_ON_US);
  PORTC &= (uint8_t)~GRID_CLEAR;
  PORTC |= GRID_CLEAR;
  PORTC &= (uint8_t)~(GRID_INHIBIT | GRID_SHIFT_LOAD);
  PORTC |= GRID_CLOCK;  /* parallel load */
  PORTC &= (uint8_t)~GRID_CLOCK;
  PORTC &= (uint8_t)~(LASER_H | LASER_V);  /* lasers off just after the load (§5.5) */
  PORTC |= GRID_SHIFT_LOAD;
  for (uint16_t k = 0; k < SENSORS; k++) {
    uint8_t data = PINA, mask = (uint8_t)(1u << (k & 7));
    if (data & _BV(0)) hits[0][k >> 3] |= mask; else hits[0][k >> 3] &= (uint8_t)~mask;
    if (data & _BV(1)) hits[1][k >> 3] |= mask; else hits[1][k >> 3] &= (uint8_t)~mask;
    PORTC |= GRID_CLOCK;
    PORTC &= (uint8_t)~GRID_CLOCK;
  }
  PORTC |= GRID_INHIBIT;
}

static void report_screen(uint8_t screen) {
  uint8_t any = 0;
  for (uint16_t k = 0; k < SENSORS; k++) {
    if (!(hits[screen][k >> 3] & (1u << (k & 7)))) continue;
    any = 1;
    put(screen ? 'V' : 'H');
    put((uint8_t)('0' + k / 100));
    put((uint8_t)('0' + k / 10 % 10));
    put((uint8_t)('0' + k % 10));
    put('X');
  }
  if (!any) put(screen ? 'v' : 'h');
}

static void report_pots(void) {
  uint8_t counts[SERVOS];
  cli();
  for (uint8_t i = 0; i < SERVOS; i++) counts[i] = pot_counts[i];
  sei();
  for (uint8_t i = 0; i < SERVOS; i++) {
    put((uint8_t)('p' + i));
    put((uint8_t)('0' + counts[i] / 100));
    put((uint8_t)('0' + counts[i] / 10 % 10));
    put((uint8_t)('0' + counts[i] % 10));
    put('X');
  }
}

static void report_capability(void) {  /* `c%05dX`: the fine reference's step, 1e-5 deg */
  uint32_t units = FINE_STEP_UNITS;
  put('c');
  for (uint32_t div = 10000; div; div /= 10) put((uint8_t)('0' + units / div % 10));
  put('X');
}

/* ---- main -------------------------------------------------------------------------------------------------- */
static void setup(void) {
  uint32_t home = pulse_q8(HOME_BYTE);
  for (uint8_t i = 0; i < SERVOS; i++) setpoint_q8[i] = target_q8[i] = home;
  DDRB |= _BV(5) | _BV(6);
  DDRE |= _BV(3) | _BV(4);
  PORTC = GRID_CLEAR | GRID_INHIBIT | GRID_SHIFT_LOAD;
  DDRC = GRID_CLOCK | GRID_SHIFT_LOAD | GRID_INHIBIT | GRID_CLEAR | LASER_H | LASER_V;
  PORTA = ADC_CS;  /* chips converting; clock idle low */
  DDRA = ADC_CS | ADC_CLOCK;  /* grid data PA0-PA1 and ADC data PA4-PA7 in */

  for (uint8_t i = 0; i < SERVOS; i++) set_compare(i, (uint16_t)((home >> 8) - 1));
  const uint8_t clock_select = TIMER_PRESCALE == 1 ? _BV(CS10) : _BV(CS11);
  ICR1 = PERIOD_TICKS - 1;
  ICR3 = PERIOD_TICKS - 1;
  TCCR1A = _BV(WGM11);
  TCCR3A = _BV(WGM31);
  TCNT1 = 0;
  TCNT3 = 0;
  TIMSK |= _BV(TOIE1);
  TCCR1B = _BV(WGM13) | _BV(WGM12) | clock_select;
  TCCR3B = _BV(WGM33) | _BV(WGM32) | clock_select;

  const uint16_t ubrr = (uint16_t)((F_CPU + 8L * BAUD) / (16L * BAUD) - 1);
  UBRR0H = (uint8_t)(ubrr >> 8);
  UBRR0L = (uint8_t)ubrr;
  UCSR0C = _BV(UCSZ01) | _BV(UCSZ00);  /* 8-N-1 */
  UCSR0B = _BV(RXEN0) | _BV(TXEN0) | _BV(RXCIE0);
  set_sleep_mode(SLEEP_MODE_IDLE);
  sei();
}

static void service_rx(void) {  /* on_byte never calls put(): safe inside its wait */
  while (rx_tail != rx_head) {
    uint8_t byte = rx_buf[rx_tail];
    rx_tail = (uint8_t)((rx_tail + 1) % sizeof rx_buf);
    on_byte(byte);
  }
}

int main(void) {
  setup();
  for (;;) {
    service_rx();
    if (z_due) {
      z_due = 0;
      put('z');
    }
    if (frame_due && started) {
      frame_due = 0;
      scan_screens();
      report_screen(0);
      report_screen(1);
    }
    if (pots_asked) {
      pots_asked--;
      report_pots();
    }
    if (capability_asked) {
      capability_asked--;
      report_capability();
    }
    cli();  /* idle until the next interrupt (the PWM tick at the latest); also makes the emulation cheap */
    if (rx_tail == rx_head && !z_due && !(frame_due && started) && !pots_asked
        && !capability_asked) {
      sleep_enable();
      sei();
      sleep_cpu();
      sleep_disable();
    }
    sei();
  }
}
