// bench-pkm5 firmware: the line protocol of docs/protocol-pkm5.md for the 5-DOF PKM controller.
//
// Hardware (shared/reference/pkm5.md §2.5): Arduino Mega 2560, six TB6560 stepper drivers, STEP/DIR pins
// (2,3) (4,5) (6,7) (8,9) (10,11) (12,13) for actuators 1-6, as in the dissertation's sketch (000 App. B.2).
// Libraries: AccelStepper (Mike McCauley), which provides MultiStepper. Flash once; moves are then commanded
// over USB serial at 115200 baud 8-N-1 instead of re-uploading a sketch for every move.
//
// Protocol summary (the document is authoritative):
//   PC -> controller   VERB [int ...] #TAG*HH\n      HH = XOR of the bytes before '*', two upper-case hex digits
//   controller -> PC   KIND #TAG FIELD ...*HH\n       KIND = OK | DONE | ERR | BOOT
//   ID, POS, STOP, ENABLE, DISABLE, SETPOS s1..s6, MOVE s1..s6 speed
// Steps are absolute, counted from full retraction (zero stroke) of each leg. At power-up the controller
// assumes the documents' home (5 mm stroke on every actuator, 000 §8.3): jog there before powering up, or SETPOS.
// The simulator (bench sim pkm5) implements the same behaviour plus simulator-only SIM* commands, which this
// firmware answers with ERR 1 SYNTAX.

#include <AccelStepper.h>
#include <MultiStepper.h>
#include <stdlib.h>
#include <string.h>

static const char DEVICE_NAME[] = "bench-pkm5";
static const int PROTOCOL_VERSION = 1;
static const char FIRMWARE_VERSION[] = "1.0.0";
static const long BAUD_RATE = 115200;

static const uint8_t AXES = 6;
static const uint8_t STEP_PINS[AXES] = {2, 4, 6, 8, 10, 12};
static const uint8_t DIR_PINS[AXES] = {3, 5, 7, 9, 11, 13};
// Enable inputs of the TB6560 boards. Not documented by the dissertation: wire EN- of each board to these pins
// (EN+ to 5 V). Check ENABLE_ACTIVE_LEVEL against your board: on most TB6560 boards a driven EN input frees
// the motor, so "enabled" is the inactive level.
static const uint8_t ENABLE_PINS[AXES] = {22, 23, 24, 25, 26, 27};
static const uint8_t ENABLE_ACTIVE_LEVEL = LOW;
// Set true for an actuator whose positive steps shorten the leg (Geometry.step_direction = -1 in motion.pkm5).
static const bool DIR_INVERTED[AXES] = {false, false, false, false, false, false};

// 66 mm stroke: 1.25 mm pitch / 200 steps (legs 1-4) and / 400 steps (legs 5-6), full stepping.
static const long MAX_STEPS[AXES] = {10560, 10560, 10560, 10560, 21120, 21120};
// 5 mm stroke: the home pose of the documents' tests.
static const long HOME_STEPS[AXES] = {800, 800, 800, 800, 1600, 1600};
// Speed of the leading axis. AccelStepper on a 16 MHz AVR manages about 4000 steps/s in total.
static const long MAX_SPEED_STEPS_S = 1000;

static const uint8_t MAX_LINE = 96;

enum ErrorCode {
  ERR_SYNTAX = 1, ERR_CHECKSUM = 2, ERR_TOO_LONG = 3, ERR_ARGUMENT = 4,
  ERR_LIMIT = 5, ERR_DISABLED = 6, ERR_BUSY = 7, ERR_STOPPED = 8
};
static const char *const ERROR_NAMES[] = {
  "", "SYNTAX", "CHECKSUM", "TOO_LONG", "ARGUMENT", "LIMIT", "DISABLED", "BUSY", "STOPPED"
};

AccelStepper steppers[AXES] = {
  AccelStepper(AccelStepper::DRIVER, STEP_PINS[0], DIR_PINS[0]),
  AccelStepper(AccelStepper::DRIVER, STEP_PINS[1], DIR_PINS[1]),
  AccelStepper(AccelStepper::DRIVER, STEP_PINS[2], DIR_PINS[2]),
  AccelStepper(AccelStepper::DRIVER, STEP_PINS[3], DIR_PINS[3]),
  AccelStepper(AccelStepper::DRIVER, STEP_PINS[4], DIR_PINS[4]),
  AccelStepper(AccelStepper::DRIVER, STEP_PINS[5], DIR_PINS[5]),
};
MultiStepper group;

static char lineBuffer[MAX_LINE + 1];
static uint8_t lineLength = 0;
static bool lineOverflow = false;
static bool enabled = false;
static bool moving = false;
static long moveTag = 0;

// ---------------------------------------------------------------------------------------------------------
// Reply output: the body is built in a buffer so that its checksum can be appended.
static char replyBuffer[MAX_LINE + 8];
static uint8_t replyLength = 0;

static void replyAppend(const char *text) {
  while (*text && replyLength < MAX_LINE) {
    replyBuffer[replyLength++] = *text++;
  }
}

static void replyAppendLong(long value) {
  char digits[13];
  ltoa(value, digits, 10);
  replyAppend(" ");
  replyAppend(digits);
}

static void replyStart(const char *kind, long tag) {
  replyLength = 0;
  replyAppend(kind);
  replyAppend(" #");
  char digits[13];
  ltoa(tag, digits, 10);
  replyAppend(digits);
}

static uint8_t xorChecksum(const char *bytes, uint8_t length) {
  uint8_t value = 0;
  for (uint8_t i = 0; i < length; i++) {
    value ^= (uint8_t)bytes[i];
  }
  return value;
}

static void replySend() {
  static const char HEX_DIGITS[] = "0123456789ABCDEF";
  uint8_t check = xorChecksum(replyBuffer, replyLength);
  replyBuffer[replyLength++] = '*';
  replyBuffer[replyLength++] = HEX_DIGITS[check >> 4];
  replyBuffer[replyLength++] = HEX_DIGITS[check & 0x0F];
  replyBuffer[replyLength++] = '\n';
  Serial.write((const uint8_t *)replyBuffer, replyLength);
}

static void replyPositions() {
  for (uint8_t i = 0; i < AXES; i++) {
    replyAppendLong(steppers[i].currentPosition());
  }
}

static void sendError(long tag, ErrorCode code) {
  replyStart("ERR", tag);
  replyAppendLong(code);
  replyAppend(" ");
  replyAppend(ERROR_NAMES[code]);
  replySend();
}

// ---------------------------------------------------------------------------------------------------------
// Motion
static void setDriversEnabled(bool on) {
  for (uint8_t i = 0; i < AXES; i++) {
    digitalWrite(ENABLE_PINS[i], on ? ENABLE_ACTIVE_LEVEL : !ENABLE_ACTIVE_LEVEL);
  }
  enabled = on;
}

static bool withinLimits(const long *steps) {
  for (uint8_t i = 0; i < AXES; i++) {
    if (steps[i] < 0 || steps[i] > MAX_STEPS[i]) {
      return false;
    }
  }
  return true;
}

static void haltAll() {
  for (uint8_t i = 0; i < AXES; i++) {
    steppers[i].moveTo(steppers[i].currentPosition());  // distanceToGo() = 0: MultiStepper.run() stops it
  }
  moving = false;
}

static void startMove(long tag, long *targets, long speed) {
  long longest = 0;
  for (uint8_t i = 0; i < AXES; i++) {
    steppers[i].setMaxSpeed((float)speed);
    long distance = labs(targets[i] - steppers[i].currentPosition());
    if (distance > longest) {
      longest = distance;
    }
  }
  group.moveTo(targets);  // scales each axis' speed so that all arrive together (constant speed)
  moving = true;
  moveTag = tag;
  replyStart("OK", tag);
  replyAppend(" MOVE");
  replyAppendLong((long)((longest * 1000L) / speed));
  replySend();
}

// ---------------------------------------------------------------------------------------------------------
// Parsing: tokens are separated by spaces; exactly one token is "#<digits>".
static bool parseLong(const char *token, long *value) {
  if (token == NULL || *token == '\0') {
    return false;
  }
  char *end = NULL;
  *value = strtol(token, &end, 10);
  return end != NULL && *end == '\0' && strlen(token) <= 11;
}

static int hexValue(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

static void executeLine(char *line, uint8_t length) {
  if (length > 0 && line[length - 1] == '\r') {
    line[--length] = '\0';
  }
  if (length == 0) {
    return;
  }
  char *star = strrchr(line, '*');
  if (star == NULL || star + 3 != line + length || hexValue(star[1]) < 0 || hexValue(star[2]) < 0) {
    sendError(0, ERR_CHECKSUM);
    return;
  }
  uint8_t bodyLength = (uint8_t)(star - line);
  if (xorChecksum(line, bodyLength) != (uint8_t)(hexValue(star[1]) * 16 + hexValue(star[2]))) {
    sendError(0, ERR_CHECKSUM);
    return;
  }
  *star = '\0';

  char *tokens[AXES + 3];
  uint8_t count = 0;
  long tag = -1;
  for (char *token = strtok(line, " "); token != NULL; token = strtok(NULL, " ")) {
    if (token[0] == '#') {
      if (tag >= 0 || !parseLong(token + 1, &tag) || tag < 0) {
        sendError(0, ERR_SYNTAX);
        return;
      }
    } else if (count < AXES + 3) {
      tokens[count++] = token;
    } else {
      sendError(tag < 0 ? 0 : tag, ERR_SYNTAX);
      return;
    }
  }
  if (tag < 0 || count == 0) {
    sendError(0, ERR_SYNTAX);
    return;
  }
  long args[AXES + 2];
  uint8_t argCount = count - 1;
  for (uint8_t i = 0; i < argCount; i++) {
    if (!parseLong(tokens[i + 1], &args[i])) {
      sendError(tag, ERR_SYNTAX);
      return;
    }
  }
  const char *verb = tokens[0];

  if (strcmp(verb, "ID") == 0 && argCount == 0) {
    replyStart("OK", tag);
    replyAppend(" ID ");
    replyAppend(DEVICE_NAME);
    replyAppendLong(PROTOCOL_VERSION);
    replyAppend(" ");
    replyAppend(FIRMWARE_VERSION);
    replySend();
  } else if (strcmp(verb, "POS") == 0 && argCount == 0) {
    replyStart("OK", tag);
    replyAppend(" POS");
    replyPositions();
    replyAppend(moving ? " MOVING" : (enabled ? " IDLE" : " DISABLED"));
    replySend();
  } else if (strcmp(verb, "STOP") == 0 && argCount == 0) {
    if (moving) {
      haltAll();
      replyStart("ERR", moveTag);
      replyAppendLong(ERR_STOPPED);
      replyAppend(" STOPPED");
      replyPositions();
      replySend();
    }
    replyStart("OK", tag);
    replyAppend(" STOP");
    replyPositions();
    replySend();
  } else if ((strcmp(verb, "ENABLE") == 0 || strcmp(verb, "DISABLE") == 0) && argCount == 0) {
    if (moving) {
      sendError(tag, ERR_BUSY);
      return;
    }
    setDriversEnabled(verb[0] == 'E');
    replyStart("OK", tag);
    replyAppend(" ");
    replyAppend(verb);
    replySend();
  } else if (strcmp(verb, "SETPOS") == 0 && argCount == AXES) {
    if (moving) {
      sendError(tag, ERR_BUSY);
    } else if (!withinLimits(args)) {
      sendError(tag, ERR_LIMIT);
    } else {
      for (uint8_t i = 0; i < AXES; i++) {
        steppers[i].setCurrentPosition(args[i]);
      }
      replyStart("OK", tag);
      replyAppend(" SETPOS");
      replySend();
    }
  } else if (strcmp(verb, "MOVE") == 0 && argCount == AXES + 1) {
    long speed = args[AXES];
    if (moving) {
      sendError(tag, ERR_BUSY);
    } else if (speed < 1 || speed > MAX_SPEED_STEPS_S) {
      sendError(tag, ERR_ARGUMENT);
    } else if (!withinLimits(args)) {
      sendError(tag, ERR_LIMIT);
    } else if (!enabled) {
      sendError(tag, ERR_DISABLED);
    } else {
      startMove(tag, args, speed);
    }
  } else {
    sendError(tag, ERR_SYNTAX);
  }
}

static void readSerial() {
  while (Serial.available() > 0) {
    char c = (char)Serial.read();
    if (c == '\n') {
      if (lineOverflow) {
        sendError(0, ERR_TOO_LONG);
      } else {
        lineBuffer[lineLength] = '\0';
        executeLine(lineBuffer, lineLength);
      }
      lineLength = 0;
      lineOverflow = false;
    } else if (lineLength >= MAX_LINE) {
      lineOverflow = true;  // keep discarding until the newline, then refuse the whole line
    } else {
      lineBuffer[lineLength++] = c;
    }
  }
}

// ---------------------------------------------------------------------------------------------------------
void setup() {
  for (uint8_t i = 0; i < AXES; i++) {
    pinMode(ENABLE_PINS[i], OUTPUT);
    steppers[i].setPinsInverted(DIR_INVERTED[i], false, false);
    steppers[i].setMaxSpeed(200.0);  // the dissertation's setMaxSpeed(200)
    steppers[i].setCurrentPosition(HOME_STEPS[i]);
    group.addStepper(steppers[i]);
  }
  setDriversEnabled(false);
  Serial.begin(BAUD_RATE);
  replyStart("BOOT", 0);
  replyAppend(" ");
  replyAppend(DEVICE_NAME);
  replyAppendLong(PROTOCOL_VERSION);
  replyAppend(" ");
  replyAppend(FIRMWARE_VERSION);
  replySend();
}

void loop() {
  readSerial();
  if (moving && !group.run()) {  // run() steps every axis that is due; false once all have arrived
    moving = false;
    replyStart("DONE", moveTag);
    replyPositions();
    replySend();
  }
}
