// A small lattice stepped inside one workgroup: every point's position and velocity at the
// stage being evaluated live in workgroup memory, the step's start and the RK sums in each
// thread's registers, and a single dispatch takes many steps, with workgroup barriers between the
// stages instead of a dispatch per stage. For a model of one body without friction or moving
// pins, of at most RESIDENT_POINTS points (the 8³ classic cube among them); larger ones step by a
// dispatch per stage (step.wgsl).
//
// The module is model.wgsl, forces.wgsl (whose `position` and `velocity` read workgroup memory
// here, defined below), contact.wgsl (which forces.wgsl names, though a model of one body never
// reaches it), check.wgsl and this file. The state is read from and written back to `base`. A
// submission's steps are counted down in status[4]: each dispatch takes at most STEPS_PER_DISPATCH of them.
// After a step that ends unsound the workgroup stops, with that step's state written back, as
// the per-stage passes leave it, and zeroes the count, so later dispatches take no step.

// Which integrator (set when the pipeline is made): 0 Euler, 1 symplectic Euler, 2 RK2, 3 RK4.
override INTEGRATOR: u32 = 3u;

// Threads, each stepping two points: at most 512 points (the host's RESIDENT_POINTS), whose
// stage takes 12 KiB of the 16 KiB of workgroup memory WebGPU guarantees.
const THREADS: u32 = 256u;
var<workgroup> stage_pos: array<f32, 1536>;
var<workgroup> stage_vel: array<f32, 1536>;
const STEPS_PER_DISPATCH: u32 = 64u;
var<workgroup> unsound: atomic<u32>;
var<workgroup> stop: u32;
var<workgroup> steps_here: u32;

fn position(i: u32) -> vec3<f32> {
    return vec3<f32>(stage_pos[3u * i], stage_pos[3u * i + 1u], stage_pos[3u * i + 2u]);
}

fn velocity(i: u32) -> vec3<f32> {
    return vec3<f32>(stage_vel[3u * i], stage_vel[3u * i + 1u], stage_vel[3u * i + 2u]);
}

fn set_stage(i: u32, p: vec3<f32>, v: vec3<f32>) {
    stage_pos[3u * i] = p.x;
    stage_pos[3u * i + 1u] = p.y;
    stage_pos[3u * i + 2u] = p.z;
    stage_vel[3u * i] = v.x;
    stage_vel[3u * i + 1u] = v.y;
    stage_vel[3u * i + 2u] = v.z;
}

// As the per-stage kernel's step end (check.wgsl), and marks the workgroup to stop after this
// step when the point is at fault.
fn check_end(i: u32, p: vec3<f32>, v: vec3<f32>) {
    if (!sound(i, p, v)) {
        atomicOr(&unsound, 1u);
        return;
    }
    record_depth(i, p);
}

// One point of a thread: the step's start, the RK sums, the slope just evaluated and the stage's
// velocity.
struct Slot {
    start_p: vec3<f32>,
    start_v: vec3<f32>,
    sum_p: vec3<f32>,
    sum_v: vec3<f32>,
    acc: vec3<f32>,
    vel: vec3<f32>,
}

// Reads point i's stage (before the stage's barrier).
fn evaluate(i: u32, slot: ptr<function, Slot>) {
    (*slot).acc = acceleration(i);
    (*slot).vel = velocity(i);
}

// Writes point i's next stage, or at the last stage its step's end (after the barrier).
fn advance(i: u32, slot: ptr<function, Slot>, stage: u32, last: bool) {
    let dt = P.law.x;
    let h = 0.5 * dt;
    let a = (*slot).acc;
    let sv = (*slot).vel;
    if (INTEGRATOR == 0u) {
        // Euler, as `euler` in step.wgsl.
        let v = sv + a * dt;
        (*slot).start_p = position(i) + sv * dt;
        (*slot).start_v = v;
    } else if (INTEGRATOR == 1u) {
        // Symplectic Euler, as `symplectic`.
        let v = sv + a * dt;
        (*slot).start_p = position(i) + v * dt;
        (*slot).start_v = v;
    } else if (INTEGRATOR == 2u) {
        // RK2, as `rk2_1` and `rk2_2`.
        if (!last) {
            set_stage(i, (*slot).start_p + sv * h, (*slot).start_v + a * h);
        } else {
            (*slot).start_p = (*slot).start_p + sv * dt;
            (*slot).start_v = (*slot).start_v + a * dt;
        }
    } else {
        // RK4, as `rk4_1` … `rk4_4`.
        if (stage == 0u) {
            (*slot).sum_p = sv;
            (*slot).sum_v = a;
            set_stage(i, (*slot).start_p + sv * h, (*slot).start_v + a * h);
        } else if (!last) {
            (*slot).sum_p = (*slot).sum_p + sv * 2.0;
            (*slot).sum_v = (*slot).sum_v + a * 2.0;
            let hs = select(h, dt, stage == 2u);
            set_stage(i, (*slot).start_p + sv * hs, (*slot).start_v + a * hs);
        } else {
            let w = dt / 6.0;
            (*slot).start_p = (*slot).start_p + ((*slot).sum_p + sv) * w;
            (*slot).start_v = (*slot).start_v + ((*slot).sum_v + a) * w;
        }
    }
    if (last) {
        set_stage(i, (*slot).start_p, (*slot).start_v);
        check_end(i, (*slot).start_p, (*slot).start_v);
    }
}

// Thread t steps points t and t + THREADS (when they exist).
@compute @workgroup_size(256)
fn resident(@builtin(local_invocation_index) t: u32) {
    let n = P.counts.x;
    let i0 = t;
    let i1 = t + THREADS;
    var s0: Slot;
    var s1: Slot;
    if (t == 0u) {
        atomicStore(&unsound, 0u);
        steps_here = min(atomicLoad(&status[4]), STEPS_PER_DISPATCH);
    }
    let steps = workgroupUniformLoad(&steps_here);
    if (i0 < n) {
        s0.start_p = base[2u * i0].xyz;
        s0.start_v = base[2u * i0 + 1u].xyz;
        set_stage(i0, s0.start_p, s0.start_v);
    }
    if (i1 < n) {
        s1.start_p = base[2u * i1].xyz;
        s1.start_v = base[2u * i1 + 1u].xyz;
        set_stage(i1, s1.start_p, s1.start_v);
    }
    workgroupBarrier();
    let stages = select(select(1u, 2u, INTEGRATOR == 2u), 4u, INTEGRATOR == 3u);
    for (var s = 0u; s < steps; s = s + 1u) {
        for (var stage = 0u; stage < stages; stage = stage + 1u) {
            // Every thread evaluates its points at the stage, then (after the barrier, when no
            // one reads the stage any more) writes the next one.
            if (i0 < n) {
                evaluate(i0, &s0);
            }
            if (i1 < n) {
                evaluate(i1, &s1);
            }
            workgroupBarrier();
            let last = stage + 1u == stages;
            if (i0 < n) {
                advance(i0, &s0, stage, last);
            }
            if (i1 < n) {
                advance(i1, &s1, stage, last);
            }
            workgroupBarrier();
        }
        if (t == 0u) {
            stop = atomicLoad(&unsound);
        }
        if (workgroupUniformLoad(&stop) != 0u) {
            break;
        }
    }
    if (t == 0u) {
        if (atomicLoad(&unsound) != 0u) {
            atomicStore(&status[4], 0u);
        } else {
            atomicSub(&status[4], steps);
        }
    }
    if (i0 < n) {
        base[2u * i0] = vec4<f32>(s0.start_p, 0.0);
        base[2u * i0 + 1u] = vec4<f32>(s0.start_v, 0.0);
    }
    if (i1 < n) {
        base[2u * i1] = vec4<f32>(s1.start_p, 0.0);
        base[2u * i1 + 1u] = vec4<f32>(s1.start_v, 0.0);
    }
}
