// The lil-gui panel: simulation parameters, worlds (examples, load, save), view toggles,
// interaction settings and capture. It holds no logic of its own: every control calls the app.
import GUI, { type Controller } from 'lil-gui';
import type { Device, Parameters } from './sim';
import type { InteractionSettings } from './interact';
import type { RenderMode } from './render';
import type { ServedWorld } from './served';

/** What the panel drives; the app implements it. */
export interface PanelHost {
  integratorNames: string[];
  /** The worlds the server offers: the user's own file, then the examples. */
  readonly worlds: ServedWorld[];
  /** The listed world now loaded (selected in the list), if it is one. */
  readonly listedWorld: ServedWorld | undefined;
  /** What the list shows when the world loaded is not one it lists. */
  readonly unlistedWorldLabel: string;
  parameters(): Parameters;
  /** True when the integrator in use is implicit (the tolerance applies). */
  readonly isImplicit: boolean;
  /** Applies parameters; returns an error message (and changes nothing) when they are invalid. */
  setParameters(p: Parameters): string | undefined;
  speed: number;
  paused: boolean;
  /** Which device steps, and what steps now (for a person). */
  device: Device;
  readonly backendLabel: string;
  mode: RenderMode;
  showKind: boolean[];
  showField: boolean;
  readonly hasField: boolean;
  interaction: InteractionSettings;
  reset(): void;
  stepOnce(): void;
  loadWorld(world: ServedWorld): void;
  openFilePicker(): void;
  save(): void;
  loadCube(n: number): void;
  resetCamera(): void;
  screenshot(): void;
  toggleSequence(): void;
  toggleVideo(): void;
  readonly canRecordVideo: boolean;
}

/** The implicit integrators' tolerances offered (m/s): from the core's default, exact to
 *  rounding in practice, to one that steps 2–3× as fast (docs/implicit.md, "Tolerance"). A
 *  scene's own value is shown as it is. */
const TOLERANCES: Record<string, number> = {
  '1e-9 (default)': 1e-9,
  '1e-7': 1e-7,
  '1e-5': 1e-5,
  '1e-3 (fastest)': 1e-3,
};

export class Panel {
  readonly gui: GUI;
  private readonly params: Parameters;
  private readonly paramControllers: Controller[] = [];
  private readonly view: { mode: RenderMode; structural: boolean; shear: boolean; bend: boolean; field: boolean };
  private readonly fieldController: Controller;
  private readonly toleranceController: Controller;
  private readonly sequenceButton: Controller;
  private readonly videoButton: Controller;
  /** The list's value: a listed world's URL, or the label of an unlisted one (lil-gui shows a
   *  value that is not among the options as it is, so the list never goes blank). */
  private readonly choice = { world: '' };
  private readonly backendText: HTMLElement;

  constructor(
    private readonly host: PanelHost,
    container: HTMLElement,
  ) {
    this.gui = new GUI({ container, title: 'Jello' });
    this.params = { ...host.parameters() };

    const sim = this.gui.addFolder('Simulation');
    const apply = () => this.applyParameters();
    this.paramControllers.push(
      sim.add(this.params, 'integrator', host.integratorNames).name('integrator').onChange(apply),
      sim.add(this.params, 'dt').name('dt (s)').decimals(6).onFinishChange(apply),
      sim.add(this.params, 'stiffness').name('stiffness (N/m)').decimals(3).onFinishChange(apply),
      sim.add(this.params, 'damping').name('damping (N·s/m)').decimals(4).onFinishChange(apply),
      sim.add(this.params, 'mass').name('mass/point (kg)').decimals(7).onFinishChange(apply),
    );
    this.toleranceController = sim.add(this.params, 'tolerance', TOLERANCES).name('tolerance (m/s)').onChange(apply);
    this.toleranceController.domElement.title = 'Residual allowed per point by the implicit integrators; unused by explicit ones';
    this.paramControllers.push(this.toleranceController);
    sim
      .add(host, 'device', { 'GPU (WebGPU) when it can': 'auto', 'CPU (wasm, f64)': 'cpu' })
      .name('device')
      .onChange(() => this.refresh());
    this.backendText = addTextRow(sim, 'stepping on', 'backend');
    this.followBackend();
    sim.add(host, 'speed', 0.05, 4, 0.05).name('speed ×').listen();
    sim.add(host, 'paused').name('paused (p)').listen();
    sim.add(host, 'stepOnce').name('single step (n)');
    sim.add(host, 'reset').name('reset to loaded world (r)');

    const worlds = this.gui.addFolder('World');
    if (host.worlds.length > 0) {
      const options = Object.fromEntries(host.worlds.map((w) => [w.label, w.url]));
      const list = worlds
        .add(this.choice, 'world', options)
        .name('showing')
        .onChange((url: string) => {
          const world = host.worlds.find((w) => w.url === url);
          if (world) host.loadWorld(world);
        });
      list.domElement.id = 'worlds';
      if (host.worlds.length === 1) list.domElement.title = 'jello view serves this file only (no examples folder found)';
    }
    worlds.add(host, 'openFilePicker').name('load .w or .toml file… (or drop one)');
    worlds.add(host, 'save').name('save state (.w; a scene as .toml)');
    const cube = { n: 12, build: () => host.loadCube(cube.n) };
    worlds.add(cube, 'n', 2, 40, 1).name('lattice n (n³ cube)');
    worlds.add(cube, 'build').name('build n³ cube under gravity');

    const view = this.gui.addFolder('View');
    this.view = {
      mode: host.mode,
      structural: host.showKind[0],
      shear: host.showKind[1],
      bend: host.showKind[2],
      field: host.showField,
    };
    view
      .add(this.view, 'mode', ['lit', 'wireframe'])
      .name('mode (v)')
      .onChange((m: RenderMode) => (host.mode = m));
    (['structural', 'shear', 'bend'] as const).forEach((kind, i) =>
      view
        .add(this.view, kind)
        .name(`${kind} (${'shb'[i]})`)
        .onChange((on: boolean) => (host.showKind[i] = on)),
    );
    this.fieldController = view
      .add(this.view, 'field')
      .name('force field arrows (f)')
      .onChange((on: boolean) => (host.showField = on));
    view.add(host, 'resetCamera').name('reset camera (e)');

    const drag = this.gui.addFolder('Interaction');
    drag.add(host.interaction, 'pullStiffness', 1, 300, 1).name('pull (N/m per kg)');
    drag.add(host.interaction, 'falloffRadius', 0, 1, 0.01).name('falloff radius (m)');
    drag.add(host.interaction, 'pushStrength', 1, 100, 1).name('push (m/s² per m)');

    const capture = this.gui.addFolder('Capture');
    capture.add(host, 'screenshot').name('screenshot (PNG)');
    this.sequenceButton = capture.add(host, 'toggleSequence').name('record frames (space)');
    this.videoButton = capture.add(host, 'toggleVideo').name('record WebM video');
    if (!host.canRecordVideo) this.videoButton.name('WebM video: not supported here').disable();
    this.refresh();
  }

  private applyParameters(): void {
    const error = this.host.setParameters({ ...this.params });
    if (error) Object.assign(this.params, this.host.parameters());
    this.showParameters();
  }

  private showParameters(): void {
    this.paramControllers.forEach((c) => c.updateDisplay());
    this.toleranceController.enable(this.host.isImplicit);
  }

  /** Shows the app's current values (after a load, a reset or a key press). */
  refresh(): void {
    this.choice.world = this.host.listedWorld?.url ?? this.host.unlistedWorldLabel;
    Object.assign(this.params, this.host.parameters());
    this.showParameters();
    Object.assign(this.view, {
      mode: this.host.mode,
      structural: this.host.showKind[0],
      shear: this.host.showKind[1],
      bend: this.host.showKind[2],
      field: this.host.showField,
    });
    this.gui.controllersRecursive().forEach((c) => c.updateDisplay());
    this.fieldController.enable(this.host.hasField);
  }

  /** Keeps the "stepping on" row current: the worker reports the backend when it has one. */
  private followBackend(): void {
    const label = this.host.backendLabel;
    if (this.backendText.textContent !== label) this.backendText.textContent = label;
    requestAnimationFrame(() => this.followBackend());
  }

  setRecordingLabels(sequence: string, video: string | undefined): void {
    this.sequenceButton.name(sequence);
    if (video !== undefined && this.host.canRecordVideo) this.videoButton.name(video);
  }
}

/** Adds a read-only row to `folder` whose text wraps onto as many lines as it needs (lil-gui's
 *  text row is one line, which cuts a long backend or adapter name off); returns the element
 *  holding the text, with the given id. */
function addTextRow(folder: GUI, name: string, id: string): HTMLElement {
  const row = document.createElement('div');
  row.className = 'lil-controller panel-text-row';
  const label = document.createElement('div');
  label.className = 'lil-name';
  label.textContent = name;
  const text = document.createElement('output');
  text.className = 'panel-text';
  text.id = id;
  row.append(label, text);
  folder.$children.append(row);
  return text;
}
