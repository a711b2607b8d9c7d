// Mouse interaction (the assignment's extra credit), on any body: drag a point of a body to pull
// it, the pull spread over its neighbours within a falloff radius; right-drag (or shift-drag) to
// push a body, or every body when the drag starts in empty space. Pulls become target springs
// and pushes an acceleration that the core evaluates inside every stage of every step; the page
// only moves the targets.
import * as THREE from 'three';
import type { Viewer } from './render';
import type { Runner } from './sim';

export interface InteractionSettings {
  /** Stiffness of the pull toward the pointer per kilogram of the body pulled (N/m per kg), so
   *  that a heavy body follows as readily as a light one; shared by the grabbed points. */
  pullStiffness: number;
  /** Rest-shape distance (m) over which a pull spreads; 0 pulls the one point. */
  falloffRadius: number;
  /** Acceleration (m/s²) of the pushed body per metre of push drag. */
  pushStrength: number;
}

interface Grab {
  kind: 'grab';
  /** Points pulled, their pull stiffness and damping, and their offsets from the grabbed point at
   *  grab time: the neighbourhood is pulled toward the pointer as a rigid patch. */
  points: Uint32Array;
  picked: number;
  stiffness: Float64Array;
  damping: Float64Array;
  offsets: THREE.Vector3[];
  anchor: THREE.Vector3;
  target: THREE.Vector3;
}

interface Push {
  kind: 'push';
  /** The body pushed, or -1 for all. */
  body: number;
  startX: number;
  startY: number;
  /** Drag in world units, in the plane facing the camera. */
  drag: THREE.Vector3;
}

export class Interaction {
  readonly settings: InteractionSettings = { pullStiffness: 40, falloffRadius: 0.2, pushStrength: 25 };
  private active: Grab | Push | undefined;
  /** Drawn while dragging: a line from the grabbed point (or the pushed body's centre) to the
   *  pointer. */
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
    const vertex = this.viewer.pickVertex(this.ndc(e));
    if (vertex === undefined && !wantsPush) return; // left drag in empty space: orbit
    e.stopImmediatePropagation();
    this.viewer.controls.enabled = false;
    this.viewer.canvas.setPointerCapture(e.pointerId);
    const sim = this.runner().sim;
    const point = vertex === undefined ? undefined : sim.surfaceVertexPoint(vertex);
    if (wantsPush) {
      const body = point === undefined ? -1 : sim.pointBodies()[point];
      this.active = { kind: 'push', body, startX: e.clientX, startY: e.clientY, drag: new THREE.Vector3() };
    } else if (point !== undefined) {
      this.startGrab(point);
    }
    this.onMove(e);
  }

  private startGrab(picked: number): void {
    const sim = this.runner().sim;
    const pos = this.positions();
    const rest = sim.restPositions();
    const bodies = sim.pointBodies();
    const active = sim.activePoints();
    const body = bodies[picked];
    const anchor = this.point(pos, picked);
    const restAnchor = this.point(rest, picked);
    const r = this.settings.falloffRadius;
    const points: number[] = [];
    const raw: number[] = [];
    let bodyPoints = 0;
    for (let i = 0; i < sim.pointCount; i++) {
      if (bodies[i] !== body || !active[i]) continue;
      bodyPoints++;
      const d = this.point(rest, i).distanceTo(restAnchor);
      if (i === picked || d < r) {
        points.push(i);
        raw.push(i === picked ? 1 : (1 - d / r) ** 2); // smooth falloff to 0 at the radius
      }
    }
    // The weights sum to 1, so the pull is one spring of stiffness k = pullStiffness · M (M the
    // body's mass) and damping c = √(k·M), half of critical for the body pulled as one, shared
    // out by weight. Each point's share of damping is capped at m/dt (m its mass), which keeps
    // the explicit integrators stable; the cap binds on the heavily weighted grabbed point.
    const total = raw.reduce((a, b) => a + b, 0);
    const mass = sim.bodyMass(body);
    const k = this.settings.pullStiffness * mass;
    const c = Math.sqrt(k * mass);
    const cMax = mass / bodyPoints / sim.dt;
    this.active = {
      kind: 'grab',
      points: Uint32Array.from(points),
      picked,
      stiffness: Float64Array.from(raw, (w) => (k * w) / total),
      damping: Float64Array.from(raw, (w) => Math.min((c * w) / total, cMax)),
      offsets: points.map((i) => this.point(pos, i).sub(anchor)),
      anchor,
      target: anchor.clone(),
    };
  }

  private onMove(e: PointerEvent): void {
    const a = this.active;
    if (!a) return;
    this.updateTarget(a, e);
    // Takes effect at once, also for single steps while paused.
    this.applyToCore();
    this.frame();
  }

  private updateTarget(a: Grab | Push, e: PointerEvent): void {
    if (a.kind === 'grab') {
      const p = this.viewer.pointerOnViewPlane(this.ndc(e), a.anchor);
      if (p) a.target.copy(p);
    } else {
      // Pixels to metres at the target's distance, along the camera's right and up.
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
    if (this.viewer.canvas.hasPointerCapture(e.pointerId)) this.viewer.canvas.releasePointerCapture(e.pointerId);
    this.release();
  }

  /** Ends a drag: the pulls and the push are removed from the core. */
  private release(): void {
    this.active = undefined;
    this.indicator.visible = false;
    this.viewer.controls.enabled = true;
    const sim = this.runner().sim;
    sim.setPulls(new Uint32Array(0), new Float64Array(0), new Float64Array(0), new Float64Array(0));
    sim.setPush(-1, 0, 0, 0);
  }

  /** Ends a drag without a pointer event (a new world was loaded: the old one holds the
   *  pulls, and is gone). */
  cancel(): void {
    this.active = undefined;
    this.indicator.visible = false;
    this.viewer.controls.enabled = true;
  }

  /** Hands the drag's targets (a grab) or acceleration (a push) to the core. */
  private applyToCore(): void {
    const a = this.active;
    if (!a) return;
    const sim = this.runner().sim;
    if (a.kind === 'push') {
      const acceleration = a.drag.clone().multiplyScalar(this.settings.pushStrength);
      sim.setPush(a.body, acceleration.x, acceleration.y, acceleration.z);
    } else {
      const targets = new Float64Array(3 * a.points.length);
      a.offsets.forEach((offset, n) => {
        const goal = a.target.clone().add(offset);
        targets.set([goal.x, goal.y, goal.z], 3 * n);
      });
      sim.setPulls(a.points, targets, a.stiffness, a.damping);
    }
  }

  /** Moves the indicator with the bodies; the app calls it every frame. */
  frame(): void {
    const a = this.active;
    if (!a) return;
    const pos = this.positions();
    if (a.kind === 'grab') {
      this.showIndicator(this.point(pos, a.picked), a.target);
      return;
    }
    const sim = this.runner().sim;
    const bodies = sim.pointBodies();
    const active = sim.activePoints();
    const centre = new THREE.Vector3();
    let n = 0;
    for (let i = 0; i < sim.pointCount; i++) {
      if (active[i] && (a.body < 0 || bodies[i] === a.body)) {
        centre.add(this.point(pos, i));
        n++;
      }
    }
    centre.divideScalar(Math.max(n, 1));
    this.showIndicator(centre, centre.clone().add(a.drag));
  }

  private showIndicator(from: THREE.Vector3, to: THREE.Vector3): void {
    const attr = this.indicator.geometry.getAttribute('position') as THREE.BufferAttribute;
    attr.setXYZ(0, from.x, from.y, from.z);
    attr.setXYZ(1, to.x, to.y, to.z);
    attr.needsUpdate = true;
    this.indicator.visible = true;
  }
}
