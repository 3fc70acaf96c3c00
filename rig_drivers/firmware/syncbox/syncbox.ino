// flexvox sync box — reference firmware for an Arduino-class board (Uno, Nano, Leonardo,
// Teensy, RP2040...). Implements rig_drivers/syncbox/PROTOCOL.md (protocol version 1).
//
// PATTERN_PIN pulses every `period_us`; FRAME_PIN pulses on every `pulses`-th pattern pulse,
// starting with the first. Pulses are PULSE_US wide, active high. Timing comes from micros()
// (4 µs resolution on 16 MHz AVR boards; use a board with a 1 µs timer, or a hardware timer,
// for periods below ~100 µs). Serial: 115200 baud, lines "<body>*XX\n", XX = XOR of body.

#include <Arduino.h>

const uint8_t PATTERN_PIN = 2;
const uint8_t FRAME_PIN = 3;
const uint32_t PULSE_US = 10;
const uint32_t MIN_PERIOD_US = 20;
const uint32_t MAX_PERIOD_US = 1000000UL;
const uint32_t MAX_PULSES = 1024;
const uint8_t MAX_LINE = 64;
const char *FIRMWARE = "flexvox-syncbox 1.0";

uint32_t period_us = 1000;
uint32_t pulses = 1;
bool running = false;
uint32_t start_us = 0;        // micros() at START
uint32_t next_us = 0;         // when the next pattern pulse is due
uint32_t count = 0;           // pattern pulses since START
uint32_t stopped_elapsed_us = 0;

char line[MAX_LINE + 1];
uint8_t line_len = 0;
bool line_overflow = false;

uint8_t xor_checksum(const char *s) {
  uint8_t c = 0;
  while (*s) c ^= (uint8_t)*s++;
  return c;
}

void reply(const char *body) {
  char buf[8];
  Serial.print(body);
  snprintf(buf, sizeof(buf), "*%02X\n", xor_checksum(body));
  Serial.print(buf);
}

void reply_number(const char *key, uint32_t value) {
  char body[MAX_LINE];
  snprintf(body, sizeof(body), "OK %s %lu", key, (unsigned long)value);
  reply(body);
}

// Parse a whole decimal number; false when empty, not digits, or too large.
bool parse_u32(const char *s, uint32_t *out) {
  if (!*s) return false;
  uint32_t v = 0;
  for (; *s; ++s) {
    if (*s < '0' || *s > '9') return false;
    if (v > 429496729UL) return false;
    v = v * 10 + (uint32_t)(*s - '0');
  }
  *out = v;
  return true;
}

void pulse_outputs() {
  bool frame = (count % pulses) == 0;
  digitalWrite(PATTERN_PIN, HIGH);
  if (frame) digitalWrite(FRAME_PIN, HIGH);
  delayMicroseconds(PULSE_US);
  digitalWrite(PATTERN_PIN, LOW);
  digitalWrite(FRAME_PIN, LOW);
  count++;
}

void execute(char *body) {
  if (strcmp(body, "VERSION?") == 0) {
    char out[MAX_LINE];
    snprintf(out, sizeof(out), "OK VERSION %s", FIRMWARE);
    reply(out);
  } else if (strcmp(body, "COUNT?") == 0) {
    reply_number("COUNT", count);
  } else if (strcmp(body, "TIME?") == 0) {
    reply_number("TIME", running ? micros() - start_us : stopped_elapsed_us);
  } else if (strcmp(body, "STATE?") == 0) {
    char out[MAX_LINE];
    snprintf(out, sizeof(out), "OK STATE %s %lu %lu", running ? "RUNNING" : "STOPPED",
             (unsigned long)period_us, (unsigned long)pulses);
    reply(out);
  } else if (strcmp(body, "START") == 0) {
    if (!running) {
      running = true;
      count = 0;
      start_us = micros();
      next_us = start_us;
    }
    reply("OK RUNNING");
  } else if (strcmp(body, "STOP") == 0) {
    if (running) {
      stopped_elapsed_us = micros() - start_us;
      running = false;
    }
    reply("OK STOPPED");
  } else if (strncmp(body, "SET PERIOD ", 11) == 0 || strncmp(body, "SET PULSES ", 11) == 0) {
    bool is_period = body[4] == 'P' && body[5] == 'E';
    uint32_t low = is_period ? MIN_PERIOD_US : 1, high = is_period ? MAX_PERIOD_US : MAX_PULSES;
    uint32_t value;
    if (running) {
      reply("ERR 4 NOT ALLOWED WHILE RUNNING");
    } else if (!parse_u32(body + 11, &value) || value < low || value > high) {
      char out[MAX_LINE];
      snprintf(out, sizeof(out), "ERR 3 BAD VALUE %s MUST BE %lu..%lu", is_period ? "PERIOD" : "PULSES",
               (unsigned long)low, (unsigned long)high);
      reply(out);
    } else {
      if (is_period) period_us = value; else pulses = value;
      reply_number(is_period ? "PERIOD" : "PULSES", value);
    }
  } else {
    reply("ERR 2 UNKNOWN COMMAND");
  }
}

// Check "<body>*XX" in place; on success cut the line at '*' and return true.
bool unframe(char *s) {
  char *star = strrchr(s, '*');
  if (!star || strlen(star) != 3) return false;
  for (char *p = s; p < star; ++p) if (*p < 0x20 || *p > 0x7E) return false;
  char hex[3] = {star[1], star[2], 0};
  char *end;
  long sent = strtol(hex, &end, 16);
  if (*end || !((hex[0] >= '0' && hex[0] <= '9') || (hex[0] >= 'A' && hex[0] <= 'F'))) return false;
  *star = 0;
  return xor_checksum(s) == (uint8_t)sent;
}

void read_serial() {
  while (Serial.available() > 0) {
    char c = (char)Serial.read();
    if (c == '\r') continue;
    if (c != '\n') {
      if (line_len < MAX_LINE - 1) line[line_len++] = c; else line_overflow = true;
      continue;
    }
    line[line_len] = 0;
    if (line_overflow) reply("ERR 5 LINE TOO LONG");
    else if (!unframe(line)) reply("ERR 1 BAD CHECKSUM");
    else execute(line);
    line_len = 0;
    line_overflow = false;
  }
}

void setup() {
  pinMode(PATTERN_PIN, OUTPUT);
  pinMode(FRAME_PIN, OUTPUT);
  digitalWrite(PATTERN_PIN, LOW);
  digitalWrite(FRAME_PIN, LOW);
  Serial.begin(115200);
}

void loop() {
  if (running && (int32_t)(micros() - next_us) >= 0) {
    pulse_outputs();
    next_us += period_us;  // scheduled from the start time: no accumulated drift
  }
  read_serial();
}
