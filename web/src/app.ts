// The app: ties the simulation glue, the renderer, the panel, interaction and capture together,
// and runs the frame loop (step to follow the wall clock, draw, capture).
import { FrameSequence, SEQUENCE_FPS, SEQUENCE_MAX, VideoRecorder, download, webmType } from './capture';
import { Panel, type PanelHost } from './gui';
import { Interaction, type InteractionSettings } from './interact';
import { Viewer, type RenderMode } from './render';
import { exampleUrl, servedWorlds, type ServedWorld, type ServerConfig } from './served';
import { JelloSim, Runner, SimView, parseWorld, sceneData, startingParameters, type Device, type Parameters, type Source } from './sim';
import { Banners, Readout, acceptDroppedFiles } from './ui';

/** Largest world or scene file accepted (bytes), as in the command line: a classic file with a
 *  30³ field is under 1 MiB, a scene with a 100 000-triangle mesh a few MiB. */
const MAX_WORLD_BYTES = 64 << 20;

export class App implements PanelHost {
  readonly viewer: Viewer;
  readonly runner: Runner;
  readonly interactionHandler: Interaction;
  readonly banners: Banners;
  readonly readout: Readout;
  readonly integratorNames = JelloSim.integratorNames();
  /** File names of the examples `jello view` serves. */
  readonly examples: string[];
  /** The worlds the panel lists: the user's own file, then the examples. */
  readonly worlds: ServedWorld[];
  panel!: Panel;
  /** The URL of the world now loaded when it came from the server (see [`listedWorld`]). */
  private loadedFrom: string | undefined;
  /** Whether the world now loaded is a cube built here rather than a file. */
  private builtHere = false;

  private sequence: FrameSequence | undefined;
  private sequenceNeedsFrame = false;
  private readonly video = new VideoRecorder();
  /** The sequence waits for the worker to take the steps of its next frame. */
  private sequenceStepping = false;
  private shownBlowUp = false;
  /** The state last drawn ([`Runner.state`] is replaced by each new one). */
  private drawnState: object | undefined;
  /** Parameters the viewer chose for the current world at load (see [`startingParameters`]),
   *  applied again on reset. */
  private startParameters: Parameters | undefined;
  /** The current world's own parameters, as loaded. */
  private ownParameters: Parameters | undefined;
  private readonly fileInput: HTMLInputElement;
  /** The step and Newton iteration counts at the last readout, and the rate it showed. */
  private lastSolverCount = { steps: 0, newton: 0 };
  private lastNewtonRate: number | undefined;

  constructor(
    canvas: HTMLCanvasElement,
    runner: Runner,
    config: ServerConfig,
    loadedFrom: string | undefined,
  ) {
    this.examples = config.examples;
    this.worlds = servedWorlds(config);
    this.loadedFrom = loadedFrom;
    this.builtHere = loadedFrom === undefined;
    this.viewer = new Viewer(canvas);
    this.runner = runner;
    this.runner.onError = (message) => this.banners.show('error', `The simulation stopped: ${message}`);
    this.interactionHandler = new Interaction(this.viewer, () => this.runner);
    this.viewer.addOverlay(this.interactionHandler.indicator);
    this.banners = new Banners(document.getElementById('banners')!);
    this.readout = new Readout(document.getElementById('readout')!);

    this.fileInput = document.createElement('input');
    this.fileInput.type = 'file';
    this.fileInput.accept = '.w,.toml,text/plain';
    this.fileInput.id = 'world-file';
    this.fileInput.hidden = true;
    this.fileInput.addEventListener('change', () => {
      const file = this.fileInput.files?.[0];
      if (file) void this.loadFile(file);
      this.fileInput.value = '';
    });
    document.body.append(this.fileInput);
    acceptDroppedFiles(document.body, (file) => void this.loadFile(file));

    this.applyStartingParameters();
    this.showWorld();
    this.panel = new Panel(this, document.getElementById('panel')!);
    this.viewer.renderer.setAnimationLoop(() => this.frame());
  }

  get sim(): SimView {
    return this.runner.sim;
  }

  /** Resolves once the stepping worker has handled every request made so far, and the state
   *  shown is from after them (for the tests and the console). */
  settled(): Promise<void> {
    return this.runner.settled();
  }

  // ---- PanelHost: the state the panel and keys change ----

  get speed(): number {
    return this.runner.speed;
  }
  set speed(s: number) {
    this.runner.speed = s;
  }
  get paused(): boolean {
    return this.runner.paused;
  }
  set paused(p: boolean) {
    this.runner.paused = p;
  }
  get mode(): RenderMode {
    return this.viewer.mode;
  }
  set mode(m: RenderMode) {
    this.viewer.mode = m;
    this.viewer.applyVisibility();
  }
  get showKind(): boolean[] {
    // A proxy-free view: the panel writes elements, so visibility is re-applied each frame.
    return this.viewer.showKind;
  }
  get showField(): boolean {
    return this.viewer.showField;
  }
  set showField(on: boolean) {
    this.viewer.showField = on;
    this.viewer.applyVisibility();
  }
  get hasField(): boolean {
    return this.viewer.hasField();
  }
  get interaction(): InteractionSettings {
    return this.interactionHandler.settings;
  }
  get canRecordVideo(): boolean {
    return webmType() !== undefined;
  }

  get worldName(): string {
    return this.sim.name;
  }

  /** The listed world now loaded, if it is one. */
  get listedWorld(): ServedWorld | undefined {
    return this.worlds.find((w) => w.url === this.loadedFrom);
  }

  /** What the list shows for a world it does not list: a file opened here or a cube built here. */
  get unlistedWorldLabel(): string {
    return `${this.sim.name} (${this.builtHere ? 'built here' : 'opened here'})`;
  }

  get device(): Device {
    return this.runner.device;
  }
  set device(d: Device) {
    this.runner.device = d;
  }

  /** What steps, for the panel: the backend, and why not the GPU when it was not chosen but
   *  does not step. */
  get backendLabel(): string {
    const b = this.sim.backend;
    if (!b) return 'starting…';
    if (b.kind === 'webgpu') return `WebGPU, f32 (${b.adapter ?? 'GPU'})`;
    return this.runner.device === 'auto' && b.why ? `CPU, wasm f64: ${b.why}` : 'CPU, wasm f64';
  }

  parameters(): Parameters {
    return this.runner.parameters();
  }

  get isImplicit(): boolean {
    return this.sim.copy.isImplicit;
  }

  setParameters(p: Parameters): string | undefined {
    try {
      this.runner.setParameters(p);
      this.afterBlowUpCleared();
      return undefined;
    } catch (e) {
      const message = errorMessage(e);
      this.banners.show('error', `Parameters not applied: ${message}`);
      return message;
    }
  }

  reset(): void {
    this.runner.reset(this.startParameters);
    this.afterBlowUpCleared();
    this.panel.refresh();
  }

  stepOnce(): void {
    this.paused = true;
    void this.runner.stepExactly(1);
  }

  loadExample(name: string): void {
    void this.loadUrl(exampleUrl(name), name);
  }

  loadWorld(world: ServedWorld): void {
    void this.loadUrl(world.url, world.name);
  }

  openFilePicker(): void {
    this.fileInput.click();
  }

  /** Downloads the current state: a scene as a scene file (.toml), anything else as a world
   *  file (.w). */
  async save(): Promise<void> {
    const scene = this.sim.isScene;
    const base = this.sim.name.replace(/\.(w|toml)$/i, '').replace(/[^\w.-]+/g, '_') || 'jello';
    try {
      const { text, time } = await this.runner.save();
      const extension = scene ? 'toml' : 'w';
      download(new Blob([text], { type: 'text/plain' }), `${base}-t${time.toFixed(3)}.${extension}`);
    } catch (e) {
      this.banners.show('error', `Cannot save: ${errorMessage(e)}`);
    }
  }

  loadCube(n: number): void {
    try {
      this.replaceSim(JelloSim.cube(n), { kind: 'cube', n }, undefined);
    } catch (e) {
      this.banners.show('error', errorMessage(e));
    }
  }

  resetCamera(): void {
    this.viewer.resetCamera();
  }

  screenshot(): void {
    this.viewer
      .snapshot()
      .then((png) => download(png, 'jello.png'))
      .catch((e: unknown) => this.banners.show('error', `Screenshot failed: ${errorMessage(e)}`));
  }

  toggleSequence(): void {
    if (this.sequence) {
      void this.finishSequence();
      return;
    }
    this.sequence = new FrameSequence();
    this.sequenceNeedsFrame = true;
    // The sequence advances by exact frames, not with the wall clock.
    this.runner.hold = true;
    this.updateRecordingUi();
  }

  toggleVideo(): void {
    if (this.video.recording) {
      this.video
        .stop()
        .then((webm) => download(webm, 'jello.webm'))
        .catch((e: unknown) => this.banners.show('error', `Video failed: ${errorMessage(e)}`))
        .finally(() => this.updateRecordingUi());
      return;
    }
    try {
      this.video.start(this.viewer.canvas);
    } catch (e) {
      this.banners.show('error', errorMessage(e));
    }
    this.updateRecordingUi();
  }

  // ---- Loading worlds ----

  /** Loads world text (fetched from the server's `from`, when it was); on error shows it and
   *  keeps the running world. */
  loadText(text: string, name: string, from?: string): boolean {
    let sim: JelloSim;
    try {
      sim = parseWorld(text, name);
    } catch (e) {
      this.banners.show('error', `Could not load ${name}: ${errorMessage(e)}. The current world keeps running.`);
      this.panel.refresh();
      return false;
    }
    this.replaceSim(sim, { kind: 'text', text, name }, from);
    return true;
  }

  async loadFile(file: File): Promise<void> {
    if (file.size > MAX_WORLD_BYTES) {
      this.banners.show('error', `${file.name}: larger than ${MAX_WORLD_BYTES >> 20} MiB, which no world file is`);
      return;
    }
    this.loadText(await file.text(), file.name);
  }

  async loadUrl(url: string, name: string): Promise<void> {
    try {
      const response = await fetch(url);
      if (!response.ok) throw new Error(`${response.status} ${response.statusText}`);
      this.loadText(await response.text(), name, url);
    } catch (e) {
      this.banners.show('error', `Could not fetch ${name}: ${errorMessage(e)}`);
      this.panel.refresh(); // the list shows the world still running, not the one that failed
    }
  }

  private replaceSim(sim: JelloSim, source: Source, from: string | undefined): void {
    this.interactionHandler.cancel();
    this.runner.replace(sim, source);
    this.loadedFrom = from;
    this.builtHere = source.kind === 'cube';
    this.lastSolverCount = { steps: 0, newton: 0 };
    this.lastNewtonRate = undefined;
    this.banners.clear('error');
    this.applyStartingParameters();
    this.afterBlowUpCleared();
    this.showWorld();
    this.panel.refresh();
  }

  /** A scene of more than 8³ points stepped by an explicit method starts with the implicit
   *  integrator at frame-rate steps (see [`startingParameters`]); a banner says so and offers
   *  the file's own. */
  private applyStartingParameters(): void {
    const own = this.runner.parameters();
    this.startParameters = startingParameters(this.sim.copy, this.runner.gpuWouldStep(this.sim.copy));
    this.ownParameters = own;
    this.banners.clear('integrator');
    if (!this.startParameters) return;
    this.runner.setParameters(this.startParameters);
    const points = this.sim.activePointCount;
    const fewer = Math.round(this.startParameters.dt / own.dt);
    this.banners.show(
      'integrator',
      `${this.sim.name} has ${points} points: running ${this.startParameters.integrator} at dt = 1/60 s (tolerance ${this.startParameters.tolerance.toExponential()} m/s), the viewer's choice above 8³ points (its own ${own.integrator} at dt = ${own.dt} s takes ${fewer}× as many steps).`,
      [{ label: `Use ${own.integrator} at dt = ${own.dt} s`, run: () => this.useOwnParameters() }],
    );
  }

  /** Back to the loaded file's own integrator and step, from the start. */
  private useOwnParameters(): void {
    this.startParameters = undefined;
    this.runner.reset();
    this.banners.clear('integrator');
    this.afterBlowUpCleared();
    this.panel.refresh();
  }

  /** When the integrator the viewer chose stops (a step that does not converge: several bodies
   *  or friction can do that), the file's own takes over from the last good state, and the
   *  banner says so. Returns whether it did. */
  private fallBackToOwnParameters(): boolean {
    const chosen = this.startParameters;
    const own = this.ownParameters;
    const now = this.runner.parameters();
    if (!chosen || !own || now.integrator !== chosen.integrator || now.dt !== chosen.dt) return false;
    const why = this.sim.blowUpMessage() ?? 'it stopped';
    this.startParameters = undefined;
    this.runner.setParameters({ ...now, integrator: own.integrator, dt: own.dt, tolerance: own.tolerance });
    this.panel.refresh();
    this.banners.show(
      'integrator',
      `${chosen.integrator} stopped (${why}); the file's own ${own.integrator} at dt = ${own.dt} s carries on from the last good state.`,
    );
    return true;
  }

  private showWorld(): void {
    this.viewer.setScene(sceneData(this.sim.copy));
    if (!this.viewer.hasField()) this.viewer.showField = false;
    this.viewer.applyVisibility();
    this.draw();
    document.title = `Jello — ${this.sim.name}`;
    const world = document.getElementById('world-name');
    if (world) world.textContent = this.sim.name;
  }

  /** Hands the current positions to the picture. */
  private draw(): void {
    this.drawnState = this.runner.state;
    this.viewer.updatePositions(this.sim.positions(), this.sim.surfacePositions());
    this.interactionHandler.frame();
  }

  private afterBlowUpCleared(): void {
    if (!this.sim.blownUp) {
      this.shownBlowUp = false;
      this.banners.clear('blowup');
    }
  }

  // ---- The frame loop ----

  private frame(): void {
    this.viewer.applyVisibility();
    // The worker steps on its own; a frame draws the latest state it sent.
    if (this.runner.state !== this.drawnState) this.draw();
    const steps = this.runner.advance();
    if (this.sequence) {
      // Recording frames: keep the frame drawn, then have the worker take exactly one frame of
      // simulated time, and wait for it.
      if (this.sequenceNeedsFrame && !this.sequenceStepping) {
        this.sequence.add(this.viewer.snapshot()); // renders, then encodes
        this.sequenceNeedsFrame = false;
        this.updateRecordingUi();
        if (this.sequence.full) void this.finishSequence();
      } else {
        this.viewer.render();
      }
      if (this.sequence && !this.sequenceStepping && !this.sequenceNeedsFrame && !this.paused && !this.sim.blownUp) {
        this.sequenceStepping = true;
        void this.runner.advanceExactly(1 / SEQUENCE_FPS).then((taken) => {
          this.sequenceStepping = false;
          this.sequenceNeedsFrame = taken > 0;
        });
      }
    } else {
      this.viewer.render();
    }
    if (!this.sim.blownUp && this.shownBlowUp) this.afterBlowUpCleared();
    this.checkBlowUp();
    this.readout.frame(steps, this.sim.dt, () => this.status());
  }

  private status(): string {
    const state = this.sim.blownUp ? 'blown up' : this.paused ? 'paused' : 'running';
    const on = this.sim.backend?.kind === 'webgpu' ? ' on WebGPU' : '';
    return `t = ${this.sim.time.toFixed(3)} s · step ${this.sim.steps} · ${state}${on}${this.newtonRate()}`;
  }

  /** The implicit solver's Newton iterations a step since the last readout; empty under an
   *  explicit integrator or before a step was taken. */
  private newtonRate(): string {
    const now = { steps: this.sim.steps, newton: this.sim.newtonIterations };
    const last = this.lastSolverCount;
    this.lastSolverCount = now;
    if (!this.isImplicit) {
      this.lastNewtonRate = undefined;
      return '';
    }
    // After a reset both counts start again; after a change of parameters only the Newton
    // iterations do (the steps go on), and that readout keeps the last rate.
    const reset = now.steps < last.steps;
    if (reset || now.newton >= last.newton) {
      const steps = reset ? now.steps : now.steps - last.steps;
      const newton = reset ? now.newton : now.newton - last.newton;
      if (steps > 0) this.lastNewtonRate = newton / steps;
    }
    return this.lastNewtonRate === undefined ? '' : ` · ${this.lastNewtonRate.toFixed(1)} Newton iterations a step`;
  }

  private checkBlowUp(): void {
    if (!this.sim.blownUp || this.shownBlowUp) return;
    if (this.fallBackToOwnParameters()) return;
    this.shownBlowUp = true;
    const suggested = this.sim.suggestedDt();
    const actions = [{ label: 'Reset', run: () => this.reset() }];
    if (suggested !== undefined) {
      actions.unshift({
        label: `Use dt = ${suggested} s and reset`,
        run: () => {
          this.reset();
          this.setParameters({ ...this.parameters(), dt: suggested });
          this.panel.refresh();
        },
      });
    }
    this.banners.show('blowup', this.sim.blowUpMessage() ?? 'The simulation blew up.', actions);
  }

  private async finishSequence(): Promise<void> {
    const sequence = this.sequence;
    this.sequence = undefined;
    this.runner.hold = false;
    this.updateRecordingUi();
    if (!sequence || sequence.count === 0) return;
    try {
      download(await sequence.zip(), 'jello-frames.zip');
      this.banners.show('info', `Saved ${sequence.count} frames (${SEQUENCE_FPS} per simulated second) as jello-frames.zip.`);
    } catch (e) {
      this.banners.show('error', `Frame capture failed: ${errorMessage(e)}`);
    }
  }

  private updateRecordingUi(): void {
    const parts: string[] = [];
    if (this.sequence) parts.push(`Recording frames: ${this.sequence.count}/${SEQUENCE_MAX} (space stops)`);
    if (this.video.recording) parts.push('Recording WebM video');
    if (parts.length > 0) this.banners.show('info', parts.join(' · '));
    else this.banners.clear('info');
    this.panel?.setRecordingLabels(
      this.sequence ? 'stop frames and download zip (space)' : 'record frames (space)',
      this.video.recording ? 'stop video and download' : 'record WebM video',
    );
  }
}

export function errorMessage(e: unknown): string {
  return e instanceof Error ? e.message : String(e);
}
