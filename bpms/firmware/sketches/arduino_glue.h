// Arduino implementations of the HAL interfaces shared by both sketches.
#ifndef BPMS_ARDUINO_GLUE_H
#define BPMS_ARDUINO_GLUE_H

#include <Arduino.h>
#include <avr/interrupt.h>
#include <avr/sleep.h>

#include "bpms_core/hal.h"

namespace bpms {

// Switch off what the board does not use. The Arduino core starts Timer1 and Timer2 for
// analogWrite() PWM, which neither sketch uses: they only draw current (and an interrupt flag
// every few microseconds). `keep_adc` for the arbiter (battery), `keep_twi` for the clusters.
inline void power_down_unused(bool keep_adc, bool keep_twi) {
    TCCR1B = 0;  // no clock source: Timer1 stopped
    TCCR2B = 0;  // Timer2 stopped
    uint8_t off = _BV(PRTIM1) | _BV(PRTIM2) | _BV(PRSPI);
    if (!keep_adc) {
        ADCSRA = 0;  // the ADC must be disabled before its clock is gated
        off |= _BV(PRADC);
    }
    if (!keep_twi) off |= _BV(PRTWI);
    PRR |= off;
}

class HardwareSerialPort : public SerialPort {
public:
    explicit HardwareSerialPort(HardwareSerial& port) : port_(port) {}
    int available() override { return port_.available(); }
    int read() override { return port_.read(); }
    void write(const uint8_t* data, uint16_t n) override { port_.write(data, n); }
    void flush() override { port_.flush(); }
    void idle() override {
        set_sleep_mode(SLEEP_MODE_IDLE);
        cli();
        if (port_.available() == 0) {
            sleep_enable();
            sei();        // the instruction after SEI runs before any interrupt: no lost wake-up
            sleep_cpu();
            sleep_disable();
        }
        sei();
    }

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
