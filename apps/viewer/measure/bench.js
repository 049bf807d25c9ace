// The playback measurement: bundled with three.js into a page; window.runBench(file) loads a
// run, then shows every frame three times (set the frame, render, read one pixel back so the
// GPU has finished) and returns the mean time per displayed frame and the load time.
import * as THREE from 'three';
import { GLTFLoader } from 'three/examples/jsm/loaders/GLTFLoader.js';
window.runBench = (file) => new Promise((resolve, reject) => {
  const t0 = performance.now();
  const renderer = new THREE.WebGLRenderer({ antialias: false });
  renderer.setSize(640, 432);
  document.body.appendChild(renderer.domElement);
  const gl = renderer.getContext();
  const px = new Uint8Array(4);
  new GLTFLoader().load(file, (gltf) => {
    const scene = new THREE.Scene();
    scene.add(new THREE.HemisphereLight(0xffffff, 0x666666, 1.2));
    const root = gltf.scene; scene.add(root);
    const camera = new THREE.PerspectiveCamera(40, 640 / 432, 0.01, 100);
    const src = gltf.cameras[0]; src.updateMatrixWorld(true);
    if (src) src.matrixWorld.decompose(camera.position, camera.quaternion, new THREE.Vector3());
    const frames = []; root.traverse((o) => { if (/^frame_\d+$/.test(o.name)) frames.push(o); });
    let morph = null; root.traverse((o) => { if (o.isMesh && o.morphTargetInfluences) morph = o; });
    const morphs = []; root.traverse((o) => { if (o.isMesh && o.morphTargetInfluences) morphs.push(o); });
    const F = frames.length || morph.morphTargetInfluences.length + 1;
    const show = (k) => {
      if (frames.length) frames.forEach((f, i) => { f.scale.set(1, 1, 1); f.visible = i === k; });
      else for (const m of morphs) { m.morphTargetInfluences.fill(0); if (k > 0) m.morphTargetInfluences[k - 1] = 1; }
    };
    show(0); renderer.render(scene, camera); gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, px);
    const load = performance.now() - t0;
    const t1 = performance.now(); let n = 0;
    for (let pass = 0; pass < 3; ++pass) for (let k = 0; k < F; ++k) { show(k); renderer.render(scene, camera); gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, px); ++n; }
    resolve({ file, frames: F, load_ms: load, ms_per_frame: (performance.now() - t1) / n });
  }, undefined, reject);
});
