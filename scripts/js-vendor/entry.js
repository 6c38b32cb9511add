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

// Show a GLB (given as base64) in a canvas inside `container`. Returns a promise resolved once drawn with
// { renderer, scene, camera, controls, view(name) } where view("top" | "oblique" | "low") moves the camera.
// Throws at once when the browser has no WebGL.
function show(container, glbBase64, options = {}) {
  const width = container.clientWidth || 800;
  const height = options.height || container.clientHeight || 520;
  const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
  renderer.setPixelRatio(Math.min(window.devicePixelRatio || 1, 2));
  renderer.setSize(width, height);
  renderer.setClearColor(0xdde6ee, 1);
  container.appendChild(renderer.domElement);
  const scene = new THREE.Scene();
  scene.add(new THREE.HemisphereLight(0xffffff, 0x445566, 1.5));
  const sun = new THREE.DirectionalLight(0xffffff, 1.8);
  sun.position.set(1, 2, 1.5);
  scene.add(sun);
  const camera = new THREE.PerspectiveCamera(45, width / height, 0.1, 100000);
  const controls = new OrbitControls(camera, renderer.domElement);
  // software WebGL (SwiftShader, llvmpipe: no GPU) draws a frame slowly: no inertia there, so a drag costs
  // one frame per mouse move instead of a long damped animation
  const gl = renderer.getContext();
  const info = gl.getExtension("WEBGL_debug_renderer_info");
  const gpu = String((info && gl.getParameter(info.UNMASKED_RENDERER_WEBGL)) || gl.getParameter(gl.RENDERER) || "");
  const software = /swiftshader|llvmpipe|softpipe|software/i.test(gpu);
  container.dataset.renderer = gpu;
  controls.enableDamping = !software;
  controls.screenSpacePanning = false;
  let dirty = true;
  controls.addEventListener("change", () => { dirty = true; });
  const loader = new GLTFLoader();
  return new Promise((resolve, reject) => {
    loader.parse(base64ToArrayBuffer(glbBase64), "", (gltf) => {
      scene.add(gltf.scene);
      const box = new THREE.Box3().setFromObject(gltf.scene);
      const size = box.getSize(new THREE.Vector3());
      const centre = box.getCenter(new THREE.Vector3());
      centre.y = 0; // look at the water level: deep bathymetry must not pull the view down
      const radius = Math.max(size.x, size.z) * 0.6 + 1;
      camera.near = radius / 1000;
      camera.far = radius * 20;
      controls.maxDistance = radius * 6;
      const views = {
        top: [0.0001, radius * 2.2, 0.0001],
        oblique: [radius * 0.13, radius * 1.25, radius * 1.38],
        low: [radius * 0.25, radius * 0.25, radius * 1.8],
      };
      const view = (name) => {
        const v = views[name] || views.oblique;
        camera.position.set(centre.x + v[0], centre.y + v[1], centre.z + v[2]);
        camera.updateProjectionMatrix();
        controls.target.copy(centre);
        controls.update();
        dirty = true;
      };
      view(options.view || "oblique");
      const resize = () => {
        const w = container.clientWidth || width;
        renderer.setSize(w, height);
        camera.aspect = w / height;
        camera.updateProjectionMatrix();
        dirty = true;
      };
      window.addEventListener("resize", resize);
      // render only while something moves: an idle report costs no CPU
      const loop = () => {
        if (controls.update() || dirty) {
          renderer.render(scene, camera);
          dirty = false;
        }
        requestAnimationFrame(loop);
      };
      renderer.render(scene, camera);
      container.dataset.drawn = "1";
      requestAnimationFrame(loop);
      resolve({ renderer, scene, camera, controls, view, software });
    }, (err) => { container.dataset.error = String(err); reject(err); });
  });
}

window.CoastforgeViewer = { show, THREE, revision: THREE.REVISION };
