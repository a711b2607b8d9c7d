// Mouse interaction (the assignment's extra credit): drag in empty space to push the whole cube,
// drag a surface point to pull it, the pull spread over neighbours within a falloff radius. Both
// become per-point forces handed to the core as Control forces; the core does the physics.
import * as THREE from 'three';
import type { Viewer } from './render';
import { forceRefreshInterval, type Runner } from './sim';

export interface InteractionSettings {
  /** Stiffness of the pull toward the pointer (N/m), shared by the grabbed points. */
  pullStiffness: number;
  /** Rest-shape distance (m) over which a pull spreads; 0 pulls the one point. */
  falloffRadius: number;
  /** Acceleration (m/s²) of the whole cube per metre of push drag. */
  pushStrength: number;
}

interface Grab {
  kind: 'grab';
  /** Points pulled, their weights (summing to 1), and their offsets from the grabbed point at
   *  grab time: the neighbourhood is pulled toward the pointer as a rigid patch. */
  points: number[];
  picked: number;
  weights: number[];
  offsets: THREE.Vector3[];
  anchor: THREE.Vector3;
  target: THREE.Vector3;
}

interface Push {
  kind: 'push';
  startX: number;
  startY: number;
  /** Drag in world units, in the plane facing the camera. */
  drag: THREE.Vector3;
}

export class Interaction {
  readonly settings: InteractionSettings = { pullStiffness: 40, falloffRadius: 0.2, pushStrength: 25 };
  private active: Grab | Push | undefined;
  private forces = new Float64Array(0);
  /** Drawn while dragging: a line from the grabbed point (or the cube's centre) to the pointer. */
  readonly indicator: THREE.Line;

  constructor(
    private readonly viewer: Viewer,
    private readonly runner: () => Runner,
  ) {
    const canvas = viewer.canvas;
    this.indicator = new THREE.Line(
      new THREE.BufferGeometry().setFromPoints([new THREE.Vector3(), new THREE.Vector3()]),
      new THREE.LineBasicMaterial({ color: 0xffee58, depthTest: false }),
    );
    this.indicator.visible = false;
    this.indicator.frustumCulled = false;
    this.indicator.renderOrder = 10;

    // Right button: ours (push), not the orbit controls' pan.
    viewer.controls.mouseButtons = { LEFT: THREE.MOUSE.ROTATE, MIDDLE: THREE.MOUSE.DOLLY, RIGHT: null };
    canvas.addEventListener('contextmenu', (e) => e.preventDefault());
    // Capture phase: decide before OrbitControls' own listener whether this drag is ours.
    canvas.addEventListener('pointerdown', (e) => this.onDown(e), { capture: true });
    canvas.addEventListener('pointermove', (e) => this.onMove(e));
    canvas.addEventListener('pointerup', (e) => this.onUp(e));
    canvas.addEventListener('pointercancel', (e) => this.onUp(e));
  }

  get dragging(): boolean {
    return this.active !== undefined;
  }

  private ndc(e: PointerEvent): THREE.Vector2 {
    const r = this.viewer.canvas.getBoundingClientRect();
    return new THREE.Vector2(((e.clientX - r.left) / r.width) * 2 - 1, -((e.clientY - r.top) / r.height) * 2 + 1);
  }

  private positions(): Float32Array {
    return this.runner().sim.positions();
  }

  private point(pos: Float32Array, i: number): THREE.Vector3 {
    return new THREE.Vector3(pos[3 * i], pos[3 * i + 1], pos[3 * i + 2]);
  }

  private onDown(e: PointerEvent): void {
    const wantsPush = e.button === 2 || (e.button === 0 && (e.shiftKey || e.ctrlKey));
    if (e.button !== 0 && e.button !== 2) return;
    const picked = e.button === 0 ? this.viewer.pickPoint(this.ndc(e)) : undefined;
    if (picked === undefined && !wantsPush) return; // left drag in empty space: orbit
    e.stopImmediatePropagation();
    this.viewer.controls.enabled = false;
    this.viewer.canvas.setPointerCapture(e.pointerId);
    if (picked !== undefined) this.startGrab(picked);
    else this.active = { kind: 'push', startX: e.clientX, startY: e.clientY, drag: new THREE.Vector3() };
    const runner = this.runner();
    this.forces = new Float64Array(3 * runner.sim.pointCount);
    runner.forceHook = () => this.applyForces();
    this.onMove(e);
  }

  private startGrab(picked: number): void {
    const sim = this.runner().sim;
    const pos = this.positions();
    const rest = sim.restPositions();
    const anchor = this.point(pos, picked);
    const restAnchor = this.point(rest, picked);
    const r = this.settings.falloffRadius;
    const points: number[] = [];
    const raw: number[] = [];
    for (let i = 0; i < sim.pointCount; i++) {
      const d = this.point(rest, i).distanceTo(restAnchor);
      if (i === picked || d < r) {
        points.push(i);
        raw.push(i === picked ? 1 : (1 - d / r) ** 2); // smooth falloff to 0 at the radius
      }
    }
    const total = raw.reduce((a, b) => a + b, 0);
    this.active = {
      kind: 'grab',
      points,
      picked,
      weights: raw.map((w) => w / total),
      offsets: points.map((i) => this.point(pos, i).sub(anchor)),
      anchor,
      target: anchor.clone(),
    };
  }

  private onMove(e: PointerEvent): void {
    const a = this.active;
    if (!a) return;
    this.updateTarget(a, e);
    // Forces take effect at once, also for single steps while paused.
    this.applyForces();
  }

  private updateTarget(a: Grab | Push, e: PointerEvent): void {
    if (a.kind === 'grab') {
      const p = this.viewer.pointerOnViewPlane(this.ndc(e), a.anchor);
      if (p) a.target.copy(p);
    } else {
      // Pixels to metres at the cube's distance, along the camera's right and up.
      const cam = this.viewer.camera;
      const distance = cam.position.distanceTo(this.viewer.controls.target);
      const perPixel = (2 * distance * Math.tan(THREE.MathUtils.degToRad(cam.fov) / 2)) / this.viewer.canvas.clientHeight;
      const right = new THREE.Vector3().setFromMatrixColumn(cam.matrixWorld, 0);
      const up = new THREE.Vector3().setFromMatrixColumn(cam.matrixWorld, 1);
      a.drag
        .copy(right)
        .multiplyScalar((e.clientX - a.startX) * perPixel)
        .addScaledVector(up, -(e.clientY - a.startY) * perPixel);
    }
  }

  private onUp(e: PointerEvent): void {
    if (!this.active) return;
    this.active = undefined;
    this.indicator.visible = false;
    this.viewer.controls.enabled = true;
    if (this.viewer.canvas.hasPointerCapture(e.pointerId)) this.viewer.canvas.releasePointerCapture(e.pointerId);
    const runner = this.runner();
    runner.forceHook = undefined;
    runner.sim.setForces(new Float64Array(0));
  }

  /** Ends a drag without a pointer event (a new world was loaded). */
  cancel(): void {
    this.active = undefined;
    this.indicator.visible = false;
    this.viewer.controls.enabled = true;
  }

  /** Computes the drag's forces from the current state and hands them to the core. */
  private applyForces(): void {
    const a = this.active;
    if (!a) return;
    const sim = this.runner().sim;
    const f = this.forces;
    f.fill(0);
    const pos = this.positions();
    if (a.kind === 'push') {
      // The same acceleration for every point: a push of the whole cube.
      const force = a.drag.clone().multiplyScalar(this.settings.pushStrength * sim.mass);
      for (let i = 0; i < sim.pointCount; i++) f.set([force.x, force.y, force.z], 3 * i);
      const centre = new THREE.Vector3();
      for (let i = 0; i < sim.pointCount; i++) centre.add(this.point(pos, i));
      centre.divideScalar(sim.pointCount);
      this.showIndicator(centre, centre.clone().add(a.drag));
    } else {
      // A damped spring from each grabbed point to its place in the patch around the pointer.
      // The weights sum to 1, so the pull is one spring of stiffness k and damping c = √(k·M)
      // (M the whole cube's mass) shared out by weight: half of critical damping (2√(k·M)) for
      // the cube pulled as one. Each point's share is capped so that a force held for one refresh
      // interval cannot reverse its velocity (explicit damping's limit); the cap binds on the
      // heavily weighted grabbed point, so the damping is less than that: a quarter to a third
      // of critical for the classic cube at the default k = 40 N/m and dt = 0.0005 s.
      const vel = sim.velocities();
      const k = this.settings.pullStiffness;
      const c = Math.sqrt(k * sim.mass * sim.pointCount);
      const cMax = sim.mass / forceRefreshInterval(sim.dt);
      a.points.forEach((i, n) => {
        const w = a.weights[n];
        const ci = Math.min(w * c, cMax);
        const goal = a.target.clone().add(a.offsets[n]);
        const p = this.point(pos, i);
        for (let axis = 0; axis < 3; axis++) {
          f[3 * i + axis] = w * k * (goal.getComponent(axis) - p.getComponent(axis)) - ci * vel[3 * i + axis];
        }
      });
      this.showIndicator(this.point(pos, a.picked), a.target);
    }
    sim.setForces(f);
  }

  private showIndicator(from: THREE.Vector3, to: THREE.Vector3): void {
    const attr = this.indicator.geometry.getAttribute('position') as THREE.BufferAttribute;
    attr.setXYZ(0, from.x, from.y, from.z);
    attr.setXYZ(1, to.x, to.y, to.z);
    attr.needsUpdate = true;
    this.indicator.visible = true;
  }
}
