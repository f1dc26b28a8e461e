// Runs the firmware's setup() once, then for each line of stdin one loop() that reads it and one idle loop()
// (in which a move started by that line completes and reports DONE).
#include "Arduino.h"
#include "AccelStepper.h"
#include "../../firmware/pkm5/pkm5.ino"
int main() {
  setup();
  while (Serial.more()) {
    Serial.lineDone = false;
    loop();
    loop();
  }
  return 0;
}
