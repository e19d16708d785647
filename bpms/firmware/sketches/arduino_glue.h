// Arduino implementations of the HAL interfaces shared by both sketches.
#ifndef BPMS_ARDUINO_GLUE_H
#define BPMS_ARDUINO_GLUE_H

#include <Arduino.h>

#include "bpms_core/hal.h"

namespace bpms {

class HardwareSerialPort : public SerialPort {
public:
    explicit HardwareSerialPort(HardwareSerial& port) : port_(port) {}
    int available() override { return port_.available(); }
    int read() override { return port_.read(); }
    void write(const uint8_t* data, uint16_t n) override { port_.write(data, n); }
    void flush() override { port_.flush(); }

private:
    HardwareSerial& port_;
};

class ArduinoClock : public Clock {
public:
    uint32_t micros() override { return ::micros(); }
    void delay_micros(uint16_t us) override { delayMicroseconds(us); }
};

class PinOut : public DigitalOut {
public:
    explicit PinOut(uint8_t pin) : pin_(pin) {}
    void begin() {
        pinMode(pin_, OUTPUT);
        digitalWrite(pin_, LOW);
    }
    void set(bool on) override { digitalWrite(pin_, on ? HIGH : LOW); }

private:
    uint8_t pin_;
};

}  // namespace bpms

#endif  // BPMS_ARDUINO_GLUE_H
