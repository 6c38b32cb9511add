// The report's 3D viewer: three.js with the GLB loader and orbit controls, exposed as window.CoastforgeViewer.
// Bundled into a single classic script because browsers refuse ES-module imports from file:// pages.
import * as THREE from "three";
import { GLTFLoader } from "three/examples/jsm/loaders/GLTFLoader.js";
import { OrbitControls } from "three/examples/jsm/controls/OrbitControls.js";

function base64ToArrayBuffer(b64) {
  const bin = atob(b64);
  const bytes = new Uint8Array(bin.length);
  for (let i = 0; i < bin.length; i++) bytes[i] = bin.charCodeAt(i);
  return bytes.buffer;
}

// Show a GLB (given as base64) in a canvas inside `container`. Returns a promise resolved once drawn.
function show(container, glbBase64, options = {}) {
  const width = container.clientWidth || 800;
  const height = options.height || 520;
  const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
  renderer.setPixelRatio(window.devicePixelRatio || 1);
  renderer.setSize(width, height);
  renderer.setClearColor(0xdde6ee, 1);
  container.appendChild(renderer.domElement);
  const scene = new THREE.Scene();
  scene.add(new THREE.HemisphereLight(0xffffff, 0x445566, 1.4));
  const sun = new THREE.DirectionalLight(0xffffff, 1.6);
  sun.position.set(1, 2, 1.5);
  scene.add(sun);
  const camera = new THREE.PerspectiveCamera(45, width / height, 0.1, 100000);
  const controls = new OrbitControls(camera, renderer.domElement);
  controls.enableDamping = true;
  const loader = new GLTFLoader();
  return new Promise((resolve, reject) => {
    loader.parse(base64ToArrayBuffer(glbBase64), "", (gltf) => {
      scene.add(gltf.scene);
      const box = new THREE.Box3().setFromObject(gltf.scene);
      const size = box.getSize(new THREE.Vector3());
      const centre = box.getCenter(new THREE.Vector3());
      const radius = Math.max(size.x, size.z) * 0.6 + 1;
      camera.position.set(centre.x + radius * 0.2, centre.y + radius * 1.1, centre.z + radius * 0.9);
      camera.near = radius / 1000;
      camera.far = radius * 20;
      camera.updateProjectionMatrix();
      controls.target.copy(centre);
      controls.update();
      const loop = () => {
        controls.update();
        renderer.render(scene, camera);
        requestAnimationFrame(loop);
      };
      loop();
      container.dataset.drawn = "1";
      resolve({ renderer, scene, camera });
    }, (err) => { container.dataset.error = String(err); reject(err); });
  });
}

window.CoastforgeViewer = { show, THREE };
