/* C peers of the benchmark scene (see common.py), float64, built by c_peer.py with
 * `gcc -O3 -march=native -fopenmp -fno-math-errno -shared -fPIC` and driven through ctypes
 * (without -fno-math-errno GCC does not vectorise the spring loop: sqrt might set errno).
 *
 * Two variants, the two baselines the speed issue names:
 *  - "simd": what a careful C programmer writes for a multi-core CPU. Structure of arrays; for
 *    each point plane and each of the 16 half-stencil offsets, the springs of a row of k are one
 *    `#pragma omp simd` loop (each spring evaluated once, one sqrt and one division), their
 *    forces written to a row buffer and then added to the first ends and subtracted from the
 *    second ends. OpenMP threads take planes i, in three phases (i mod 3) so that no two threads
 *    write the same plane (a spring reaches at most two planes on). A point loop adds gravity and
 *    the walls and forms the next RK stage.
 *  - "naive": the textbook loop. Arrays of 3-vectors, one flat spring list, one thread.
 * GCC's default floating-point contraction (GNU C mode) is left on, as a user compiling with
 * -march=native would have it: results differ from Jello's in the last bits, well inside
 * check.py's tolerance.
 */
#include <math.h>
#include <omp.h>
#include <stdlib.h>
#include <string.h>

#define K_ELASTIC 200.0
#define D_ELASTIC 0.25
#define K_COLLISION 400.0
#define D_COLLISION 0.25
#define MASS (1.0 / 512.0)
#define GRAVITY (-9.81 * MASS)
#define BOX 2.0

static const int OFFSETS[16][3] = {
    {1, 0, 0},  {0, 1, 0},  {0, 0, 1},                                     /* structural */
    {1, 1, 0},  {1, -1, 0}, {1, 0, 1},  {1, 0, -1}, {0, 1, 1}, {0, 1, -1}, /* face shear */
    {1, 1, 1},  {1, 1, -1}, {1, -1, 1}, {1, -1, -1},                       /* body shear */
    {2, 0, 0},  {0, 2, 0},  {0, 0, 2},                                     /* bend */
};

typedef struct {
    int n, threads, rk4, naive;
    long points;
    double dt;
    double rest[16];
    /* State, stage and RK4 sums: 3 components of `points` each (x block, y block, z block). */
    double *p, *v, *sp, *sv, *sum_p, *sum_v, *acc, *force;
    /* Per thread: a row of forces (3 × n). */
    double *rows;
    /* Naive: the spring list. */
    long springs;
    int *sa, *sb;
    double *srest;
} Sim;

static double *alloc(long count) {
    double *d = aligned_alloc(64, ((count * sizeof(double) + 63) / 64) * 64);
    if (d) memset(d, 0, count * sizeof(double));
    return d;
}

/* Wall penalty along one axis. */
static inline double wall(double c, double v) {
    if (c < -BOX) return K_COLLISION * (-BOX - c) - D_COLLISION * v;
    if (c > BOX) return -K_COLLISION * (c - BOX) - D_COLLISION * v;
    return 0.0;
}

/* Accelerations at positions q and velocities w (both x|y|z blocks) into s->acc. */
static void accelerations_simd(Sim *s, const double *q, const double *w) {
    const int n = s->n;
    const long P = s->points, plane = (long)n * n;
    double *restrict f = s->force;
    const double *qx = q, *qy = q + P, *qz = q + 2 * P;
    const double *wx = w, *wy = w + P, *wz = w + 2 * P;
    double *fx = f, *fy = f + P, *fz = f + 2 * P;
#pragma omp parallel for schedule(static) num_threads(s->threads)
    for (long t = 0; t < 3 * P; t++) f[t] = 0.0;
    for (int phase = 0; phase < 3; phase++) {
#pragma omp parallel for schedule(static) num_threads(s->threads)
        for (int i = phase; i < n; i += 3) {
            double *rx = s->rows + (long)omp_get_thread_num() * 3 * n;
            double *ry = rx + n, *rz = rx + 2 * n;
            for (int o = 0; o < 16; o++) {
                const int di = OFFSETS[o][0], dj = OFFSETS[o][1], dk = OFFSETS[o][2];
                if (i + di >= n) continue;
                const int j0 = dj < 0 ? -dj : 0, j1 = dj > 0 ? n - dj : n;
                const int k0 = dk < 0 ? -dk : 0, k1 = dk > 0 ? n - dk : n;
                const long shift = ((long)di * n + dj) * n + dk;
                const double rest = s->rest[o];
                for (int j = j0; j < j1; j++) {
                    const long a0 = (long)i * plane + (long)j * n;
                    const long b0 = a0 + shift;
#pragma omp simd
                    for (int k = k0; k < k1; k++) {
                        const long a = a0 + k, b = b0 + k;
                        const double dx = qx[a] - qx[b], dy = qy[a] - qy[b], dz = qz[a] - qz[b];
                        const double l = sqrt(dx * dx + dy * dy + dz * dz);
                        const double inv = 1.0 / l;
                        const double closing =
                            ((wx[a] - wx[b]) * dx + (wy[a] - wy[b]) * dy + (wz[a] - wz[b]) * dz) * inv;
                        const double m = (-K_ELASTIC * (l - rest) - D_ELASTIC * closing) * inv;
                        rx[k] = dx * m;
                        ry[k] = dy * m;
                        rz[k] = dz * m;
                    }
#pragma omp simd
                    for (int k = k0; k < k1; k++) {
                        fx[a0 + k] += rx[k];
                        fy[a0 + k] += ry[k];
                        fz[a0 + k] += rz[k];
                    }
#pragma omp simd
                    for (int k = k0; k < k1; k++) {
                        fx[b0 + k] -= rx[k];
                        fy[b0 + k] -= ry[k];
                        fz[b0 + k] -= rz[k];
                    }
                }
            }
        }
    }
    double *ax = s->acc, *ay = ax + P, *az = ax + 2 * P;
#pragma omp parallel for simd schedule(static) num_threads(s->threads)
    for (long t = 0; t < P; t++) {
        ax[t] = (fx[t] + wall(qx[t], wx[t])) / MASS;
        ay[t] = (fy[t] + wall(qy[t], wy[t])) / MASS;
        az[t] = (fz[t] + GRAVITY + wall(qz[t], wz[t])) / MASS;
    }
}

/* The same from the spring list, point by point, on one thread. */
static void accelerations_naive(Sim *s, const double *q, const double *w) {
    const long P = s->points;
    double *f = s->force;
    memset(f, 0, 3 * P * sizeof(double));
    for (long t = 0; t < s->springs; t++) {
        const long a = s->sa[t], b = s->sb[t];
        double d[3], u[3], dv = 0.0, l = 0.0;
        for (int c = 0; c < 3; c++) {
            d[c] = q[c * P + a] - q[c * P + b];
            l += d[c] * d[c];
        }
        l = sqrt(l);
        for (int c = 0; c < 3; c++) {
            u[c] = d[c] / l;
            dv += (w[c * P + a] - w[c * P + b]) * u[c];
        }
        const double m = -K_ELASTIC * (l - s->srest[t]) - D_ELASTIC * dv;
        for (int c = 0; c < 3; c++) {
            f[c * P + a] += m * u[c];
            f[c * P + b] -= m * u[c];
        }
    }
    for (long t = 0; t < P; t++) {
        for (int c = 0; c < 3; c++) {
            double g = c == 2 ? GRAVITY : 0.0;
            s->acc[c * P + t] = (f[c * P + t] + g + wall(q[c * P + t], w[c * P + t])) / MASS;
        }
    }
}

static void accelerations(Sim *s, const double *q, const double *w) {
    if (s->naive)
        accelerations_naive(s, q, w);
    else
        accelerations_simd(s, q, w);
}

/* One step: RK4 (stages at y, y + dt/2 k1, y + dt/2 k2, y + dt k3) or explicit Euler. */
static void step(Sim *s) {
    const long N = 3 * s->points;
    const double dt = s->dt;
    double *p = s->p, *v = s->v, *sp = s->sp, *sv = s->sv, *a = s->acc;
    double *sum_p = s->sum_p, *sum_v = s->sum_v;
    const int T = s->naive ? 1 : s->threads;
    accelerations(s, p, v);
    if (!s->rk4) {
#pragma omp parallel for simd schedule(static) num_threads(T)
        for (long t = 0; t < N; t++) {
            p[t] += dt * v[t];
            v[t] += dt * a[t];
        }
        return;
    }
#pragma omp parallel for simd schedule(static) num_threads(T)
    for (long t = 0; t < N; t++) {
        sum_p[t] = v[t];
        sum_v[t] = a[t];
        sp[t] = p[t] + 0.5 * dt * v[t];
        sv[t] = v[t] + 0.5 * dt * a[t];
    }
    for (int stage = 2; stage <= 3; stage++) {
        accelerations(s, sp, sv);
        const double h = stage == 2 ? 0.5 * dt : dt;
#pragma omp parallel for simd schedule(static) num_threads(T)
        for (long t = 0; t < N; t++) {
            sum_p[t] += 2.0 * sv[t];
            sum_v[t] += 2.0 * a[t];
            sp[t] = p[t] + h * sv[t];
            sv[t] = v[t] + h * a[t];
        }
    }
    accelerations(s, sp, sv);
#pragma omp parallel for simd schedule(static) num_threads(T)
    for (long t = 0; t < N; t++) {
        p[t] += dt / 6.0 * (sum_p[t] + sv[t]);
        v[t] += dt / 6.0 * (sum_v[t] + a[t]);
    }
}

/* A simulation of the N³ scene from positions and velocities given as (points, 3) arrays. */
Sim *sim_new(int n, int rk4, int naive, int threads, double dt, const double *pos,
             const double *vel) {
    Sim *s = calloc(1, sizeof(Sim));
    if (!s) return NULL;
    s->n = n;
    s->rk4 = rk4;
    s->naive = naive;
    s->threads = threads;
    s->dt = dt;
    s->points = (long)n * n * n;
    const long P = s->points;
    const double h = 1.0 / (n - 1);
    for (int o = 0; o < 16; o++) {
        const int *d = OFFSETS[o];
        s->rest[o] = h * sqrt((double)(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]));
    }
    double **bufs[] = {&s->p, &s->v, &s->sp, &s->sv, &s->sum_p, &s->sum_v, &s->acc, &s->force};
    for (unsigned b = 0; b < sizeof bufs / sizeof bufs[0]; b++)
        if (!(*bufs[b] = alloc(3 * P))) return NULL;
    if (!(s->rows = alloc((long)threads * 3 * n))) return NULL;
    for (long t = 0; t < P; t++)
        for (int c = 0; c < 3; c++) {
            s->p[c * P + t] = pos[3 * t + c];
            s->v[c * P + t] = vel[3 * t + c];
        }
    if (naive) {
        long count = 0;
        for (int pass = 0; pass < 2; pass++) {
            count = 0;
            for (int o = 0; o < 16; o++)
                for (int i = 0; i < n; i++)
                    for (int j = 0; j < n; j++)
                        for (int k = 0; k < n; k++) {
                            const int i2 = i + OFFSETS[o][0], j2 = j + OFFSETS[o][1],
                                      k2 = k + OFFSETS[o][2];
                            if (i2 >= n || j2 < 0 || j2 >= n || k2 < 0 || k2 >= n) continue;
                            if (pass == 1) {
                                s->sa[count] = (i * n + j) * n + k;
                                s->sb[count] = (i2 * n + j2) * n + k2;
                                s->srest[count] = s->rest[o];
                            }
                            count++;
                        }
            if (pass == 0) {
                s->springs = count;
                s->sa = malloc(count * sizeof(int));
                s->sb = malloc(count * sizeof(int));
                s->srest = malloc(count * sizeof(double));
                if (!s->sa || !s->sb || !s->srest) return NULL;
            }
        }
    }
    return s;
}

void sim_step(Sim *s, long steps) {
    for (long t = 0; t < steps; t++) step(s);
}

/* Positions and velocities as (points, 3) arrays. */
void sim_state(const Sim *s, double *pos, double *vel) {
    const long P = s->points;
    for (long t = 0; t < P; t++)
        for (int c = 0; c < 3; c++) {
            pos[3 * t + c] = s->p[c * P + t];
            vel[3 * t + c] = s->v[c * P + t];
        }
}

void sim_free(Sim *s) {
    if (!s) return;
    double *bufs[] = {s->p, s->v, s->sp, s->sv, s->sum_p, s->sum_v, s->acc, s->force, s->rows,
                      s->srest};
    for (unsigned b = 0; b < sizeof bufs / sizeof bufs[0]; b++) free(bufs[b]);
    free(s->sa);
    free(s->sb);
    free(s);
}
