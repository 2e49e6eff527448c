/* rhi_template_device: the skeleton of a real device on the rhi device protocol v1.1.
 *
 * Fill in the four callbacks below for your hardware (each marked HARDWARE); the loop, the sessions, the
 * watchdog, the e-stop and the torque clamp are the kit's (rhi_device.c). As shipped, the callbacks report
 * that no hardware is attached, so the device latches FAULT and commands zero torque: it never moves a motor
 * until you write them.
 *
 *   rhi_template_device [--port 5005]
 */
#define _POSIX_C_SOURCE 200809L

#include "rhi_device.h"

#include <errno.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#define N 4 /* motors */

static const char *const SENSOR_NAMES[] = {"ft"}; /* docs/protocol.md lists the names rhi understands */
static const uint16_t SENSOR_WIDTHS[] = {6};
static const double TAU_MAX[N] = {3.0, 3.0, 1.0, 1.0}; /* [N m]: your drives' limits */
static const double TAU_MIN[N] = {-3.0, -3.0, -1.0, -1.0};

/* HARDWARE: read the encoders: q [rad] and dq [rad/s] in motor coordinates. Return 0, or -1 on a driver error. */
static int read_encoders(double *q, double *dq) {
    int i;
    for (i = 0; i < N; i++) { q[i] = 0.0; dq[i] = 0.0; }
    return -1; /* no hardware attached */
}

/* HARDWARE: read the sensors, in SENSOR_NAMES order (ft: tared force [N] then torque [N m], base axes). */
static int read_sensors(double *s) {
    int i;
    for (i = 0; i < 6; i++) s[i] = 0.0;
    return -1;
}

/* HARDWARE: command the motor torques [N m] (already clamped); enable = 0: disable the drives. */
static int write_torques(const double *tau, int enable) {
    (void)tau;
    (void)enable;
    return -1;
}

/* HARDWARE: the hardware e-stop button (1: pressed). */
static int estop_pressed(void) { return 0; }

static volatile sig_atomic_t stop_requested = 0;
static void on_signal(int sig) { (void)sig; stop_requested = 1; }

int main(int argc, char **argv) {
    double q[N], dq[N], s[6], tau[N], period, t0, t_next;
    rhi_device d;
    rhi_config cfg;
    int port = argc > 2 && !strcmp(argv[1], "--port") ? atoi(argv[2]) : 5005;
    memset(&cfg, 0, sizeof cfg);
    cfg.name = "my-device"; /* the host matches it (rhi run --device-name my-device) */
    cfg.n = N;
    cfg.rate = 1000.0;
    cfg.watchdog = 0.02;
    cfg.session_timeout = 1.0;
    cfg.tau_min = TAU_MIN;
    cfg.tau_max = TAU_MAX;
    cfg.n_sensors = 1;
    cfg.sensor_names = SENSOR_NAMES;
    cfg.sensor_widths = SENSOR_WIDTHS;
    if (rhi_device_open(&d, &cfg, "0.0.0.0", (uint16_t)port) < 0) {
        perror("rhi_template_device: cannot listen");
        return 1;
    }
    signal(SIGINT, on_signal);
    signal(SIGTERM, on_signal);
    period = 1.0 / cfg.rate;
    t0 = t_next = rhi_now();
    while (!stop_requested) {
        struct timespec ts;
        if (read_encoders(q, dq) < 0 || read_sensors(s) < 0) rhi_device_fault(&d); /* latched: zero torque */
        if (estop_pressed()) d.estop = 1;                                          /* cleared by a RESET command */
        rhi_device_send_reading(&d, rhi_now() - t0, q, dq, s);
        t_next += period;
        rhi_device_poll(&d, t_next - rhi_now());
        if (write_torques(tau, rhi_device_torque(&d, rhi_now(), tau)) < 0) rhi_device_fault(&d);
        if (t_next < rhi_now() - 10 * period) t_next = rhi_now();
        ts.tv_sec = (time_t)t_next;
        ts.tv_nsec = (long)((t_next - (double)ts.tv_sec) * 1e9);
        while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, NULL) == EINTR && !stop_requested) {}
    }
    {
        double zero[N] = {0};
        write_torques(zero, 0);
    }
    rhi_device_close(&d);
    return 0;
}
