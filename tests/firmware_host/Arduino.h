// Host stand-in for the Arduino core, just enough to run firmware/pkm5/pkm5.ino on a PC for protocol tests.
#pragma once
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#define LOW 0
#define HIGH 1
#define OUTPUT 1
inline void pinMode(int, int) {}
inline void digitalWrite(int, int) {}
inline char *ltoa(long value, char *buffer, int) { sprintf(buffer, "%ld", value); return buffer; }
struct HostSerial {  // stdin/stdout instead of the UART; one line of input per loop() (see host_main.cpp)
  bool lineDone = false;
  void begin(long) {}
  int available() { if (lineDone) return 0; int c = getchar(); if (c == EOF) return 0; ungetc(c, stdin); return 1; }
  int read() { int c = getchar(); lineDone = (c == '\n'); return c; }
  bool more() { int c = getchar(); if (c == EOF) return false; ungetc(c, stdin); return true; }
  size_t write(const uint8_t *bytes, size_t n) { size_t w = fwrite(bytes, 1, n, stdout); fflush(stdout); return w; }
};
static HostSerial Serial;
