// The three.js picture: the bodies (lit skins or cage surfaces, or the cages' wireframe), pinned
// points, the bounding box, the inclined plane and plane obstacles clipped to the box, sphere and
// box obstacles, force-field arrows, lights and the orbiting camera. It only draws what the
// simulation glue hands it; no physics here.
import * as THREE from 'three';
import { OrbitControls } from 'three/examples/jsm/controls/OrbitControls.js';

/** What the renderer needs from a loaded world or scene; read once per file. */
export interface SceneData {
  /** Lattice points of every body (the wireframe and pins are drawn over them). */
  pointCount: number;
  /** Vertices of the lit surface: skins, and cage surfaces of bodies without one. */
  surfaceVertexCount: number;
  /** Lit surface triangles, three surface-vertex indices each. */
  triangles: Uint32Array;
  /** Per surface vertex: its body (for its colour). */
  surfaceBodies: Uint32Array;
  /** Points on the cages' surfaces (the wireframe's dots). */
  surfacePoints: Uint32Array;
  /** Spring end pairs with both ends on the surface, per kind: structural, shear, bend. */
  springs: [Uint32Array, Uint32Array, Uint32Array];
  /** `[minx, miny, minz, maxx, maxy, maxz]`. */
  box: Float64Array;
  /** `[a, b, c, d]` of `a x + b y + c z + d = 0`, or undefined. */
  plane: Float64Array | undefined;
  /** `[x, y, z, fx, fy, fz, …]` at the field nodes, `i` outermost; empty without a field. */
  field: Float32Array;
  fieldRes: number;
  /** Obstacles, seven numbers each: kind (0 plane, 1 sphere, 2 box) and six values. */
  obstacles: Float64Array;
  /** Pinned points. */
  pins: Uint32Array;
}

export type RenderMode = 'lit' | 'wireframe';
export const SPRING_KINDS = ['structural', 'shear', 'bend'] as const;

const SPRING_COLOURS = [0x4fc3f7, 0xffb74d, 0xce93d8];
/** Body colours in turn; the first is the classic jello's red. */
const BODY_COLOURS = [0xe0405a, 0x43a047, 0xffb300, 0x1e88e5, 0x8e24aa, 0x00acc1, 0xf4511e];
const OBSTACLE_COLOUR = 0x78909c;
const BACKGROUND = 0x16181d;

/** Body `b`'s colour: the palette's in turn, then a hue of its own for each further body (the
 *  golden angle apart, light and dark by turns), so bodies in a pile of many do not share one. */
export function bodyColour(b: number, colour = new THREE.Color()): THREE.Color {
  if (b < BODY_COLOURS.length) return colour.setHex(BODY_COLOURS[b]);
  const n = b - BODY_COLOURS.length;
  return colour.setHSL((0.13 + n * 0.381966) % 1, 0.7, n % 2 === 0 ? 0.42 : 0.6, THREE.SRGBColorSpace);
}

/** The camera the original program starts with, and `e` returns to (z is up), for its box of
 *  4 m a side centred on the origin; another box is framed alike (see [`Viewer.frameBox`]). */
const HOME = { radius: 11, azimuth: Math.PI / 5, elevation: Math.PI / 7 };
/** Half the diagonal of the original program's box: at HOME.radius, a box of this half diagonal
 *  fills the view as that one did. */
const HOME_HALF_DIAGONAL = 2 * Math.sqrt(3);

export class Viewer {
  readonly renderer: THREE.WebGLRenderer;
  readonly camera: THREE.PerspectiveCamera;
  readonly controls: OrbitControls;
  private readonly scene = new THREE.Scene();
  private readonly world = new THREE.Group(); // everything rebuilt per loaded world

  /** Lattice points (wireframe, pins). */
  private positions = new THREE.BufferAttribute(new Float32Array(0), 3);
  /** Surface vertices (the lit mesh). */
  private surfacePositions = new THREE.BufferAttribute(new Float32Array(0), 3);
  private surface!: THREE.Mesh<THREE.BufferGeometry, THREE.MeshPhongMaterial>;
  private wirePoints!: THREE.Points;
  private pinPoints!: THREE.Points;
  private wireSprings: THREE.LineSegments[] = [];
  private fieldArrows: THREE.LineSegments | undefined;
  /** The current world's box, which the home camera frames. */
  private box: number[] = [-2, -2, -2, 2, 2, 2];

  mode: RenderMode = 'lit';
  readonly showKind = [true, true, true];
  showField = false;

  constructor(readonly canvas: HTMLCanvasElement) {
    this.renderer = new THREE.WebGLRenderer({ canvas, antialias: false });
    this.renderer.setPixelRatio(Math.min(window.devicePixelRatio, 2));
    this.scene.background = new THREE.Color(BACKGROUND);

    this.camera = new THREE.PerspectiveCamera(40, 1, 0.05, 100);
    this.camera.up.set(0, 0, 1); // the simulation's z is up
    this.controls = new OrbitControls(this.camera, canvas);
    this.controls.enableDamping = false;
    this.resetCamera();

    this.addLights();
    this.scene.add(this.world);
  }

  /** Eight coloured point lights at the corners of the box, as the original lit its jello, plus
   *  a soft fill so no side goes black. */
  private addLights(): void {
    const colours = [0xff8a80, 0xffd180, 0xffff8d, 0xccff90, 0x84ffff, 0x82b1ff, 0xb388ff, 0xffffff];
    let n = 0;
    for (const x of [-2, 2])
      for (const y of [-2, 2])
        for (const z of [-2, 2]) {
          const light = new THREE.PointLight(colours[n++], 0.55, 0, 0);
          light.position.set(x * 1.2, y * 1.2, z * 1.2);
          this.scene.add(light);
        }
    this.scene.add(new THREE.HemisphereLight(0xdde6ff, 0x302020, 0.6));
  }

  /** Adds an object that outlives worlds (the drag indicator). */
  addOverlay(object: THREE.Object3D): void {
    this.scene.add(object);
  }

  /** Builds the objects of a newly loaded world. */
  setScene(data: SceneData): void {
    // A world in another box: the camera goes home to frame it (the same box keeps the camera).
    const box = Array.from(data.box);
    if (box.some((x, i) => x !== this.box[i])) {
      this.box = box;
      this.resetCamera();
    }
    for (const child of [...this.world.children]) {
      this.world.remove(child);
      disposeObject(child);
    }
    this.positions = new THREE.BufferAttribute(new Float32Array(3 * data.pointCount), 3);
    this.positions.setUsage(THREE.DynamicDrawUsage);
    this.surfacePositions = new THREE.BufferAttribute(new Float32Array(3 * data.surfaceVertexCount), 3);
    this.surfacePositions.setUsage(THREE.DynamicDrawUsage);

    // Lit surface: smooth normals over shared vertices, a colour per body.
    const surfaceGeometry = new THREE.BufferGeometry();
    surfaceGeometry.setAttribute('position', this.surfacePositions);
    surfaceGeometry.setIndex(new THREE.BufferAttribute(data.triangles, 1));
    surfaceGeometry.setAttribute(
      'normal',
      new THREE.BufferAttribute(new Float32Array(3 * data.surfaceVertexCount), 3),
    );
    const colours = new Float32Array(3 * data.surfaceVertexCount);
    const colour = new THREE.Color();
    data.surfaceBodies.forEach((b, v) => {
      bodyColour(b, colour);
      colours.set([colour.r, colour.g, colour.b], 3 * v);
    });
    surfaceGeometry.setAttribute('color', new THREE.BufferAttribute(colours, 3));
    this.surface = new THREE.Mesh(
      surfaceGeometry,
      new THREE.MeshPhongMaterial({
        vertexColors: true,
        specular: 0x8a8a8a,
        shininess: 70,
        side: THREE.DoubleSide,
      }),
    );
    this.world.add(this.surface);

    // Wireframe: surface points and the springs between them, one object per kind.
    const pointGeometry = new THREE.BufferGeometry();
    pointGeometry.setAttribute('position', this.positions);
    pointGeometry.setIndex(new THREE.BufferAttribute(data.surfacePoints, 1));
    this.wirePoints = new THREE.Points(
      pointGeometry,
      new THREE.PointsMaterial({ color: 0xffffff, size: 4, sizeAttenuation: false }),
    );
    this.world.add(this.wirePoints);
    this.wireSprings = data.springs.map((pairs, kind) => {
      const g = new THREE.BufferGeometry();
      g.setAttribute('position', this.positions);
      g.setIndex(new THREE.BufferAttribute(pairs, 1));
      const lines = new THREE.LineSegments(
        g,
        new THREE.LineBasicMaterial({ color: SPRING_COLOURS[kind], transparent: true, opacity: 0.85 }),
      );
      this.world.add(lines);
      return lines;
    });

    // Pinned points, in both modes.
    const pinGeometry = new THREE.BufferGeometry();
    pinGeometry.setAttribute('position', this.positions);
    pinGeometry.setIndex(new THREE.BufferAttribute(data.pins, 1));
    this.pinPoints = new THREE.Points(
      pinGeometry,
      new THREE.PointsMaterial({ color: 0xffee58, size: 8, sizeAttenuation: false, depthTest: false }),
    );
    this.pinPoints.renderOrder = 5;
    this.world.add(this.pinPoints);

    this.world.add(boxLines(data.box));
    if (data.plane) {
      const plane = planeInBox(data.plane, data.box);
      if (plane) this.world.add(plane);
    }
    for (let o = 0; o + 7 <= data.obstacles.length; o += 7) {
      const shape = obstacle(data.obstacles.subarray(o, o + 7), data.box);
      if (shape) this.world.add(shape);
    }
    // The bodies move every frame: skip culling rather than recompute bounds each time.
    for (const o of [this.surface, this.wirePoints, this.pinPoints, ...this.wireSprings]) o.frustumCulled = false;
    this.fieldArrows = data.fieldRes > 0 ? fieldArrows(data.field, data.fieldRes, data.box) : undefined;
    if (this.fieldArrows) this.world.add(this.fieldArrows);
    this.applyVisibility();
  }

  /** New positions: of the lattice points and of the surface vertices (`Float32Array`s of 3
   *  per point or vertex); normals follow. */
  updatePositions(points: Float32Array, surface: Float32Array): void {
    (this.positions.array as Float32Array).set(points);
    this.positions.needsUpdate = true;
    (this.surfacePositions.array as Float32Array).set(surface);
    this.surfacePositions.needsUpdate = true;
    this.surface.geometry.computeVertexNormals();
  }

  applyVisibility(): void {
    const wire = this.mode === 'wireframe';
    this.surface.visible = !wire;
    this.wirePoints.visible = wire;
    this.wireSprings.forEach((lines, kind) => (lines.visible = wire && this.showKind[kind]));
    if (this.fieldArrows) this.fieldArrows.visible = this.showField;
  }

  hasField(): boolean {
    return this.fieldArrows !== undefined;
  }

  resize(): void {
    const { clientWidth: w, clientHeight: h } = this.canvas;
    if (w === 0 || h === 0) return;
    const size = this.renderer.getSize(new THREE.Vector2());
    if (size.x !== w || size.y !== h) {
      this.renderer.setSize(w, h, false);
      this.camera.aspect = w / h;
      this.camera.updateProjectionMatrix();
    }
  }

  render(): void {
    this.resize();
    this.controls.update();
    this.renderer.render(this.scene, this.camera);
  }

  /** The home camera: the current world's box seen from the home direction. */
  resetCamera(): void {
    this.frameBox(this.box);
  }

  /** Looks from the home direction at the centre of `[minx, miny, minz, maxx, maxy, maxz]`, from
   *  as far as frames it as the home camera frames the original 4 m box (11 m from its centre). */
  frameBox(box: ArrayLike<number>): void {
    const [x0, y0, z0, x1, y1, z1] = Array.from(box);
    const centre = new THREE.Vector3((x0 + x1) / 2, (y0 + y1) / 2, (z0 + z1) / 2);
    const halfDiagonal = Math.hypot(x1 - x0, y1 - y0, z1 - z0) / 2;
    const radius = Math.max(HOME.radius * (halfDiagonal / HOME_HALF_DIAGONAL), 0.05);
    const { azimuth, elevation } = HOME;
    // The original box's zoom limits (1 m to 40 m) and clipping planes, widened in proportion
    // for a much smaller or larger box.
    const scale = radius / HOME.radius;
    this.controls.minDistance = Math.min(1, scale);
    this.controls.maxDistance = 40 * Math.max(1, scale);
    this.camera.near = 0.05 * Math.min(1, scale);
    this.camera.far = 100 * Math.max(1, scale);
    this.camera.updateProjectionMatrix();
    this.camera.position.set(
      centre.x + radius * Math.cos(elevation) * Math.cos(azimuth),
      centre.y + radius * Math.cos(elevation) * Math.sin(azimuth),
      centre.z + radius * Math.sin(elevation),
    );
    this.controls.target.copy(centre);
    this.controls.update();
  }

  /** Moves the camera toward (factor < 1) or away from (factor > 1) its target. */
  zoom(factor: number): void {
    const offset = this.camera.position.clone().sub(this.controls.target);
    const length = THREE.MathUtils.clamp(
      offset.length() * factor,
      this.controls.minDistance,
      this.controls.maxDistance,
    );
    this.camera.position.copy(this.controls.target).add(offset.setLength(length));
    this.controls.update();
  }

  /** The surface vertex under the pointer (normalised device coordinates), or undefined. */
  pickVertex(ndc: THREE.Vector2): number | undefined {
    const ray = new THREE.Raycaster();
    ray.setFromCamera(ndc, this.camera);
    this.surface.geometry.computeBoundingSphere(); // the raycast's early-out uses it
    const hit = ray.intersectObject(this.surface, false)[0];
    if (!hit?.face) return undefined;
    // The hit triangle's corner nearest the hit.
    const p = this.surfacePositions;
    const corners = [hit.face.a, hit.face.b, hit.face.c];
    let best = corners[0];
    let bestDistance = Infinity;
    for (const c of corners) {
      const d = hit.point.distanceToSquared(new THREE.Vector3(p.getX(c), p.getY(c), p.getZ(c)));
      if (d < bestDistance) [best, bestDistance] = [c, d];
    }
    return best;
  }

  /** Where the pointer ray meets the plane through `anchor` facing the camera. */
  pointerOnViewPlane(ndc: THREE.Vector2, anchor: THREE.Vector3): THREE.Vector3 | undefined {
    const ray = new THREE.Raycaster();
    ray.setFromCamera(ndc, this.camera);
    const normal = this.camera.getWorldDirection(new THREE.Vector3());
    const plane = new THREE.Plane().setFromNormalAndCoplanarPoint(normal, anchor);
    return ray.ray.intersectPlane(plane, new THREE.Vector3()) ?? undefined;
  }

  /** Renders now and encodes the canvas as PNG (rendering first, so the drawing buffer holds the
   *  frame even without preserveDrawingBuffer). */
  snapshot(): Promise<Blob> {
    this.render();
    return new Promise((resolve, reject) =>
      this.canvas.toBlob((b) => (b ? resolve(b) : reject(new Error('the canvas gave no image'))), 'image/png'),
    );
  }
}

function disposeObject(object: THREE.Object3D): void {
  object.traverse((o) => {
    const m = o as THREE.Mesh;
    if (m.geometry) m.geometry.dispose();
    const material = m.material as THREE.Material | THREE.Material[] | undefined;
    if (Array.isArray(material)) material.forEach((x) => x.dispose());
    else material?.dispose();
  });
}

/** The 12 edges of the bounding box and a faint grid on its floor. */
function boxLines(box: Float64Array): THREE.Group {
  const [x0, y0, z0, x1, y1, z1] = box;
  const group = new THREE.Group();
  const size = new THREE.Vector3(x1 - x0, y1 - y0, z1 - z0);
  const edges = new THREE.LineSegments(
    new THREE.EdgesGeometry(new THREE.BoxGeometry(size.x, size.y, size.z)),
    new THREE.LineBasicMaterial({ color: 0xb0bec5 }),
  );
  edges.position.set((x0 + x1) / 2, (y0 + y1) / 2, (z0 + z1) / 2);
  group.add(edges);
  const grid = new THREE.GridHelper(1, 8, 0x3a4250, 0x3a4250);
  grid.rotation.x = Math.PI / 2; // GridHelper lies in xz; ours is the floor z = z0
  grid.scale.set(size.x, 1, size.y);
  grid.position.set((x0 + x1) / 2, (y0 + y1) / 2, z0 + 1e-3);
  group.add(grid);
  return group;
}

/** An obstacle (kind and six values, as `SceneData.obstacles`): a sphere or box drawn solid and
 *  translucent, a plane clipped to the box. */
function obstacle(o: Float64Array, box: Float64Array): THREE.Object3D | undefined {
  const material = () =>
    new THREE.MeshPhongMaterial({ color: OBSTACLE_COLOUR, transparent: true, opacity: 0.55, shininess: 20 });
  switch (o[0]) {
    case 0:
      return planeInBox(o.subarray(1, 5), box);
    case 1: {
      const sphere = new THREE.Mesh(new THREE.SphereGeometry(o[4], 48, 24), material());
      sphere.position.set(o[1], o[2], o[3]);
      return sphere;
    }
    case 2: {
      const [x0, y0, z0, x1, y1, z1] = o.subarray(1, 7);
      const solid = new THREE.Mesh(new THREE.BoxGeometry(x1 - x0, y1 - y0, z1 - z0), material());
      solid.position.set((x0 + x1) / 2, (y0 + y1) / 2, (z0 + z1) / 2);
      return solid;
    }
    default:
      return undefined;
  }
}

/** The inclined plane clipped to the box: the polygon where the plane cuts the box, filled and
 *  outlined. Undefined when the plane misses the box. */
function planeInBox(coeffs: Float64Array, box: Float64Array): THREE.Group | undefined {
  const [a, b, c, d] = coeffs;
  const [x0, y0, z0, x1, y1, z1] = box;
  const value = (p: THREE.Vector3) => a * p.x + b * p.y + c * p.z + d;
  const corners: THREE.Vector3[] = [];
  for (const x of [x0, x1]) for (const y of [y0, y1]) for (const z of [z0, z1]) corners.push(new THREE.Vector3(x, y, z));
  // Box edges join corners that differ in one coordinate.
  const cuts: THREE.Vector3[] = [];
  for (let i = 0; i < 8; i++)
    for (let j = i + 1; j < 8; j++) {
      const diff = i ^ j;
      if (diff !== 1 && diff !== 2 && diff !== 4) continue;
      const [vi, vj] = [value(corners[i]), value(corners[j])];
      if ((vi < 0 && vj > 0) || (vi > 0 && vj < 0)) cuts.push(corners[i].clone().lerp(corners[j], vi / (vi - vj)));
      else if (vi === 0) cuts.push(corners[i].clone());
    }
  if (cuts.length < 3) return undefined;
  // Order the cut points around their centre, in the plane's own basis.
  const normal = new THREE.Vector3(a, b, c).normalize();
  const centre = cuts.reduce((s, p) => s.add(p), new THREE.Vector3()).divideScalar(cuts.length);
  const u = new THREE.Vector3().crossVectors(normal, Math.abs(normal.x) < 0.9 ? new THREE.Vector3(1, 0, 0) : new THREE.Vector3(0, 1, 0)).normalize();
  const v = new THREE.Vector3().crossVectors(normal, u);
  const angle = (p: THREE.Vector3) => {
    const r = p.clone().sub(centre);
    return Math.atan2(r.dot(v), r.dot(u));
  };
  cuts.sort((p, q) => angle(p) - angle(q));
  const vertices: number[] = [];
  for (let i = 1; i + 1 < cuts.length; i++) for (const p of [cuts[0], cuts[i], cuts[i + 1]]) vertices.push(p.x, p.y, p.z);
  const fill = new THREE.BufferGeometry();
  fill.setAttribute('position', new THREE.Float32BufferAttribute(vertices, 3));
  const group = new THREE.Group();
  group.add(
    new THREE.Mesh(
      fill,
      new THREE.MeshBasicMaterial({ color: 0x5c9ded, transparent: true, opacity: 0.22, side: THREE.DoubleSide, depthWrite: false }),
    ),
  );
  const outline = new THREE.LineLoop(
    new THREE.BufferGeometry().setFromPoints(cuts),
    new THREE.LineBasicMaterial({ color: 0x8ab8f5 }),
  );
  group.add(outline);
  return group;
}

/** Arrows (a shaft and two barbs each, one draw call) at field nodes, at most about 8 per axis,
 *  scaled so the strongest is 0.4 m long. */
function fieldArrows(samples: Float32Array, res: number, box: Float64Array): THREE.LineSegments | undefined {
  const stride = Math.max(1, Math.ceil(res / 8));
  let max = 0;
  for (let n = 0; n < samples.length; n += 6) max = Math.max(max, Math.hypot(samples[n + 3], samples[n + 4], samples[n + 5]));
  if (max === 0) return undefined;
  const scale = (0.4 * Math.min(box[3] - box[0], 4)) / 4 / max;
  const vertices: number[] = [];
  const dir = new THREE.Vector3();
  const side = new THREE.Vector3();
  for (let i = 0; i < res; i += stride)
    for (let j = 0; j < res; j += stride)
      for (let k = 0; k < res; k += stride) {
        const n = 6 * ((i * res + j) * res + k);
        const p = new THREE.Vector3(samples[n], samples[n + 1], samples[n + 2]);
        dir.set(samples[n + 3], samples[n + 4], samples[n + 5]).multiplyScalar(scale);
        if (dir.lengthSq() < 1e-8) continue;
        const tip = p.clone().add(dir);
        vertices.push(p.x, p.y, p.z, tip.x, tip.y, tip.z);
        // Two barbs in a plane holding the arrow.
        side.crossVectors(dir, Math.abs(dir.z) < 0.9 * dir.length() ? new THREE.Vector3(0, 0, 1) : new THREE.Vector3(1, 0, 0));
        side.setLength(dir.length() * 0.15);
        for (const s of [1, -1]) {
          const barb = tip.clone().addScaledVector(dir, -0.3).addScaledVector(side, s);
          vertices.push(tip.x, tip.y, tip.z, barb.x, barb.y, barb.z);
        }
      }
  const g = new THREE.BufferGeometry();
  g.setAttribute('position', new THREE.Float32BufferAttribute(vertices, 3));
  return new THREE.LineSegments(g, new THREE.LineBasicMaterial({ color: 0x9ccc65, transparent: true, opacity: 0.7 }));
}
