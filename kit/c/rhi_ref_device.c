/* rhi_ref_device: a reference device on the rhi device protocol v1.1, simulating a plant at its own rate.
 *
 * The plant is generic: n decoupled joints, each a rotor of inertia I [kg m^2] with viscous damping b
 * [N m s/rad] and a spring k [N m/rad] to its start q0 (a device held by a compliant fixture), integrated
 * with semi-implicit Euler at the device rate:  I q'' = tau - b q' - k (q - q0).  It reports a 6-float
 * "ft" sensor (zeros: no hand touches it) and sets SIMULATED in every reading.
 *
 *   rhi_ref_device [--host 127.0.0.1] [--port 5005] [--rate 1000] [--watchdog 0.02] [--name c-ref]
 *                  [--q0 a,b,c,d] [--tau-max a,b,c,d] [--inertia 0.02] [--damping 0.5] [--stiffness 5]
 *                  [--duration S]
 * It prints its address on the first line, a line per session event, and its counts at exit (SIGINT/SIGTERM).
 */
#define _POSIX_C_SOURCE 200809L

#include "rhi_device.h"

#include <errno.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

static volatile sig_atomic_t stop_requested = 0;
static void on_signal(int sig) { (void)sig; stop_requested = 1; }

static int parse_list(const char *s, double *out, int max) {
    int n = 0;
    char *end;
    while (*s && n < max) {
        out[n++] = strtod(s, &end);
        if (end == s) return -1;
        s = *end == ',' ? end + 1 : end;
    }
    return n;
}

static void sleep_until(double t) {
    struct timespec ts;
    ts.tv_sec = (time_t)t;
    ts.tv_nsec = (long)((t - (double)ts.tv_sec) * 1e9);
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, NULL) == EINTR && !stop_requested) {}
}

int main(int argc, char **argv) {
    const char *host = "127.0.0.1", *name = "c-ref";
    static const char *const sensor_names[] = {"ft"};
    static const uint16_t sensor_widths[] = {6};
    double rate = 1000.0, watchdog = 0.02, duration = -1.0, I = 0.02, b = 0.5, kk = 5.0;
    double q0[RHI_MAX_N] = {0}, q[RHI_MAX_N], dq[RHI_MAX_N], tau[RHI_MAX_N], lo[RHI_MAX_N], hi[RHI_MAX_N];
    double s[6] = {0}, period, t0, t_next;
    int n = 4, i, port = 5005, nq = -1, nt = -1;
    unsigned long k = 0, events = 0;
    rhi_device d;
    rhi_config cfg;
    for (i = 0; i < RHI_MAX_N; i++) hi[i] = 3.0;
    for (i = 1; i < argc; i++) {
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        if (!v) { fprintf(stderr, "rhi_ref_device: %s needs a value\n", a); return 2; }
        if (!strcmp(a, "--host")) host = v;
        else if (!strcmp(a, "--port")) port = atoi(v);
        else if (!strcmp(a, "--rate")) rate = atof(v);
        else if (!strcmp(a, "--watchdog")) watchdog = atof(v);
        else if (!strcmp(a, "--name")) name = v;
        else if (!strcmp(a, "--q0")) nq = parse_list(v, q0, RHI_MAX_N);
        else if (!strcmp(a, "--tau-max")) nt = parse_list(v, hi, RHI_MAX_N);
        else if (!strcmp(a, "--inertia")) I = atof(v);
        else if (!strcmp(a, "--damping")) b = atof(v);
        else if (!strcmp(a, "--stiffness")) kk = atof(v);
        else if (!strcmp(a, "--duration")) duration = atof(v);
        else { fprintf(stderr, "rhi_ref_device: unknown option %s\n", a); return 2; }
        i++;
    }
    if (nq > 0) n = nq;
    if (nq == 0 || (nt >= 0 && nt != n) || port < 0 || port > 65535 || !(rate > 0) || !(I > 0) || b < 0 || kk < 0) {
        fprintf(stderr, "rhi_ref_device: bad options (q0 and tau-max need n values; rate and inertia > 0)\n");
        return 2;
    }
    for (i = 0; i < n; i++) { lo[i] = -hi[i]; q[i] = q0[i]; dq[i] = 0.0; }
    memset(&cfg, 0, sizeof cfg);
    cfg.name = name;
    cfg.n = (uint16_t)n;
    cfg.rate = rate;
    cfg.watchdog = watchdog;
    cfg.session_timeout = 1.0;
    cfg.tau_min = lo;
    cfg.tau_max = hi;
    cfg.n_sensors = 1;
    cfg.sensor_names = sensor_names;
    cfg.sensor_widths = sensor_widths;
    cfg.status_bits = RHI_SIMULATED;
    if (rhi_device_open(&d, &cfg, host, (uint16_t)port) < 0) {
        perror("rhi_ref_device: cannot listen");
        return 1;
    }
    signal(SIGINT, on_signal);
    signal(SIGTERM, on_signal);
    printf("rhi_ref_device: %s, %d motors, %g Hz, watchdog %g s on udp://%s:%u\n", name, n, rate, watchdog, host,
           (unsigned)rhi_device_port(&d));
    fflush(stdout);
    period = 1.0 / rate;
    t0 = rhi_now();
    t_next = t0;
    while (!stop_requested && (duration < 0 || (double)k * period < duration)) {
        double now, t = rhi_now() - t0; /* the device clock: seconds since start, monotonic */
        if (!rhi_device_active(&d)) { /* idle until a HELLO */
            rhi_device_poll(&d, 0.05);
            t_next = rhi_now();
        } else {
            rhi_device_send_reading(&d, t, q, dq, s);
            t_next += period;
            rhi_device_poll(&d, t_next - rhi_now());
            now = rhi_now();
            rhi_device_torque(&d, now, tau);
            for (i = 0; i < n; i++) { /* one period of the plant */
                dq[i] += period * (tau[i] - b * dq[i] - kk * (q[i] - q0[i])) / I;
                q[i] += period * dq[i];
            }
            k++;
            if (t_next < now - 10 * period) t_next = now; /* far behind (suspended): no burst */
            sleep_until(t_next);
        }
        if (d.events != events) {
            events = d.events;
            printf("rhi_ref_device: %s\n", d.event);
            fflush(stdout);
        }
    }
    printf("rhi_ref_device: periods %lu readings %lu commands %lu invalid %lu foreign %lu stale_commands %lu "
           "refused %lu takeovers %lu watchdog_trips %lu sessions %lu\n", k, d.stats.readings, d.stats.commands,
           d.stats.invalid, d.stats.foreign, d.stats.stale_commands, d.stats.refused, d.stats.takeovers,
           d.stats.watchdog_trips, d.stats.sessions);
    rhi_device_close(&d);
    return 0;
}
