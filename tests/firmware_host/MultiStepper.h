// Host stand-in for MultiStepper: the first run() after moveTo() reports the move in progress, the next arrives.
#pragma once
#include "AccelStepper.h"
class MultiStepper {
 public:
  bool addStepper(AccelStepper &s) { steppers_[count_++] = &s; return true; }
  void moveTo(long *targets) { for (int i = 0; i < count_; i++) steppers_[i]->moveTo(targets[i]); pending_ = true; }
  bool run() {
    if (pending_) { pending_ = false; return true; }
    for (int i = 0; i < count_; i++) steppers_[i]->arrive();
    return false;
  }
 private:
  AccelStepper *steppers_[10];
  int count_ = 0;
  bool pending_ = false;
};
