// Host stand-in for AccelStepper: positions only, moves complete instantly.
#pragma once
#include "Arduino.h"
class AccelStepper {
 public:
  enum { DRIVER = 1 };
  AccelStepper(int, int, int) {}
  long currentPosition() { return position_; }
  void moveTo(long target) { target_ = target; }
  long distanceToGo() { return target_ - position_; }
  void setMaxSpeed(float) {}
  void setCurrentPosition(long p) { position_ = target_ = p; }
  void setPinsInverted(bool, bool, bool) {}
  void arrive() { position_ = target_; }
 private:
  long position_ = 0, target_ = 0;
};
