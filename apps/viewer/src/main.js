// The drape viewer: plays the run.glb that `drape view OUT_DIR` serves next to this page.
// The file's layout (apps/drape/gltf.h): frame nodes "frame_NNNNN" under the root, one shown at a
// time; obstacles; a camera. The page shows frame k by making its node the only visible one,
// so the slider, the play loop and a ?frame=K in the address (which moves the slider) all set
// the same state.
import * as THREE from 'three';
import { GLTFLoader } from 'three/examples/jsm/loaders/GLTFLoader.js';
import { OrbitControls } from 'three/examples/jsm/controls/OrbitControls.js';

const params = new URLSearchParams(location.search);
const view = document.getElementById('view');
const slider = document.getElementById('frame');
const label = document.getElementById('label');
const playButton = document.getElementById('play');
const speed = document.getElementById('speed');
const wire = document.getElementById('wire');

const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
renderer.setPixelRatio(window.devicePixelRatio);
renderer.setClearColor(0xffffff);
view.appendChild(renderer.domElement);
const scene = new THREE.Scene();
scene.add(new THREE.HemisphereLight(0xffffff, 0x666666, 1.2));
const camera = new THREE.PerspectiveCamera(40, 1, 0.01, 1000);
const key = new THREE.DirectionalLight(0xffffff, 1.8);
camera.add(key);  // the light moves with the camera: over its left shoulder, as `drape render --style shaded`
key.position.set(-0.45, 0.65, 1);
scene.add(camera);
const controls = new OrbitControls(camera, renderer.domElement);

// The sheets' two sides in two colours (as `drape render --style shaded`), obstacles grey.
const front = new THREE.MeshStandardMaterial({ color: 0xe28b3a, side: THREE.FrontSide, roughness: 0.8 });
const back = new THREE.MeshStandardMaterial({ color: 0x4876c4, side: THREE.BackSide, roughness: 0.8 });
const solid = new THREE.MeshStandardMaterial({ color: 0xb0b2b8, roughness: 0.6 });
const materials = [front, back, solid];

let frames = [];   // the frame nodes, in order
let times = [];    // their simulated times, s
let current = -1, playing = false, clock = 0, last = 0;

function show(k) {
  k = Math.max(0, Math.min(frames.length - 1, k | 0));
  if (k === current) return;
  if (current >= 0) frames[current].visible = false;
  frames[k].visible = true;
  current = k;
  slider.value = String(k);
  label.textContent = `frame ${k}/${frames.length - 1}, t = ${times[k].toFixed(3)} s`;
}

function resize() {
  const w = view.clientWidth, h = view.clientHeight;
  renderer.setSize(w, h);
  camera.aspect = w / h;
  camera.updateProjectionMatrix();
}

function setPlaying(on) {
  playing = on && frames.length > 1;
  playButton.textContent = playing ? 'Pause' : 'Play';
  if (playing && current === frames.length - 1) show(0);
  clock = times[current] - times[0];
}

function loop(now) {
  const dt = (now - last) / 1000;
  last = now;
  if (playing) {
    clock += dt * Number(speed.value);
    const t = times[0] + clock;
    let k = current;
    while (k + 1 < frames.length && times[k + 1] <= t) ++k;
    show(k);
    if (k === frames.length - 1) setPlaying(false);
  }
  controls.update();
  renderer.render(scene, camera);
  requestAnimationFrame(loop);
}

function fail(text) {
  document.getElementById('message').textContent = text;
  document.title = 'drape viewer: error';
}

new GLTFLoader().load(params.get('file') || 'run.glb', (gltf) => {
  const root = gltf.scene;
  const info = (root.userData && root.userData.drape) || {};
  root.traverse((o) => {
    if (/^frame_\d+$/.test(o.name) && o.parent && o.parent.parent === root) frames.push(o);
  });
  if (frames.length === 0) { fail('run.glb has no frame nodes (frame_00000, …)'); return; }
  frames.sort((a, b) => a.name.localeCompare(b.name));
  times = info.times || frames.map((_, k) => k);
  for (const f of frames) {
    f.scale.set(1, 1, 1);  // the file hides frames by scale for readers that play its animation
    f.visible = false;
    const meshes = [];
    f.traverse((o) => { if (o.isMesh) meshes.push(o); });
    for (const m of meshes) {
      m.material = front;
      const b = new THREE.Mesh(m.geometry, back);
      m.add(b);
    }
  }
  root.traverse((o) => { if (o.isMesh && /^obstacle\d+$/.test(o.name)) o.material = solid; });
  scene.add(root);
  scene.updateMatrixWorld(true);

  // Start from the file's camera (the scene's, or drape's automatic framing).
  const source = gltf.cameras[0];
  if (source) {
    source.updateMatrixWorld(true);
    source.matrixWorld.decompose(camera.position, camera.quaternion, new THREE.Vector3());
    camera.fov = source.fov;
    const forward = new THREE.Vector3(0, 0, -1).applyQuaternion(camera.quaternion);
    const box = new THREE.Box3().setFromObject(root);
    const centre = box.getCenter(new THREE.Vector3());
    const distance = Math.max(0.01, centre.clone().sub(camera.position).dot(forward));
    controls.target.copy(camera.position).addScaledVector(forward, distance);
  }
  slider.max = String(frames.length - 1);
  resize();
  show(0);
  if (params.has('frame')) {  // as if the user had dragged the slider there
    slider.value = params.get('frame');
    slider.dispatchEvent(new Event('input'));
  }
  if (params.get('play') === '1') setPlaying(true);
  document.title = `drape viewer: ${info.frames || frames.length} frames`;
  requestAnimationFrame((now) => { last = now; loop(now); });
}, undefined, (error) => fail(`cannot load run.glb: ${error.message || error}`));

slider.addEventListener('input', () => { show(Number(slider.value)); clock = times[current] - times[0]; });
playButton.addEventListener('click', () => setPlaying(!playing));
wire.addEventListener('change', () => { for (const m of materials) m.wireframe = wire.checked; });
window.addEventListener('keydown', (e) => { if (e.code === 'Space') { setPlaying(!playing); e.preventDefault(); } });
window.addEventListener('resize', resize);
