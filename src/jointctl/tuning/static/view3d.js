// jointctl tuning page: the 3D view. The server sends the world's visible shapes ("scene": MuJoCo
// geoms, z up, sizes as MuJoCo gives them) and their poses ("poses", 30 per second of loop time);
// three.js draws them. Drag to orbit, wheel to zoom. window.jointctl3d is read by the browser tests.
import * as THREE from "./vendor/three.module.js";

// ?view3d=0 leaves the view out (for comparing the page's cost with and without it).
const box = document.getElementById("view3d");
if (new URLSearchParams(location.search).get("view3d") === "0") {
  box.hidden = true;
  box.previousElementSibling.hidden = true;
} else {
  start();
}

function start() {
  const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
  renderer.setPixelRatio(1);
  box.appendChild(renderer.domElement);
  const scene = new THREE.Scene();
  scene.background = new THREE.Color(0xf4f6f8);
  scene.add(new THREE.AmbientLight(0xffffff, 0.7));
  const sun = new THREE.DirectionalLight(0xffffff, 1.6);
  sun.position.set(3, -5, 8);
  scene.add(sun);
  const camera = new THREE.PerspectiveCamera(45, 1, 0.02, 200);
  camera.up.set(0, 0, 1);  // MuJoCo's z up
  const orbit = { lookat: [0, 0, 1], distance: 5, azimuth: 90, elevation: -15 };  // MuJoCo's free camera, degrees
  let meshes = [];
  let labels = [];
  let frames = 0;
  let dirty = true;

  function placeCamera() {
    const az = THREE.MathUtils.degToRad(orbit.azimuth), el = THREE.MathUtils.degToRad(orbit.elevation);
    const forward = new THREE.Vector3(Math.cos(el) * Math.cos(az), Math.cos(el) * Math.sin(az), Math.sin(el));
    const target = new THREE.Vector3(...orbit.lookat);
    camera.position.copy(target).addScaledVector(forward, -orbit.distance);
    camera.lookAt(target);
    camera.updateMatrixWorld();
    dirty = true;
  }

  function resize() {
    const width = Math.max(200, box.clientWidth), height = Math.round(width * 0.6);
    renderer.setSize(width, height, true);
    camera.aspect = width / height;
    camera.updateProjectionMatrix();
    dirty = true;
  }

  function geometryOf(g) {
    const s = g.size;
    switch (g.type) {
      case "box": return new THREE.BoxGeometry(2 * s[0], 2 * s[1], 2 * s[2]);
      case "sphere": return new THREE.SphereGeometry(s[0], 24, 16);
      case "ellipsoid": return new THREE.SphereGeometry(1, 24, 16).scale(s[0], s[1], s[2]);
      case "cylinder": return new THREE.CylinderGeometry(s[0], s[0], 2 * s[1], 32).rotateX(Math.PI / 2);
      case "capsule": return new THREE.CapsuleGeometry(s[0], 2 * s[1], 8, 24).rotateX(Math.PI / 2);
      case "plane": return new THREE.PlaneGeometry(2 * (s[0] || 10), 2 * (s[1] || 10));
      case "mesh": {
        const geometry = new THREE.BufferGeometry();
        geometry.setAttribute("position", new THREE.Float32BufferAttribute(g.vertices, 3));
        geometry.setIndex(g.faces);
        geometry.computeVertexNormals();
        return geometry;
      }
      default: return null;
    }
  }

  function buildScene(message) {
    for (const mesh of meshes) { scene.remove(mesh); mesh.geometry.dispose(); mesh.material.dispose(); }
    meshes = [];
    labels = [];
    for (const g of message.geoms) {
      const geometry = geometryOf(g);
      if (!geometry) continue;
      const [r, gr, b, a] = g.rgba;
      const material = new THREE.MeshStandardMaterial({ color: new THREE.Color(r, gr, b), transparent: a < 1, opacity: a,
                                                        roughness: 0.7, metalness: 0.1 });
      const mesh = new THREE.Mesh(geometry, material);
      scene.add(mesh);
      meshes.push(mesh);
      labels.push(g.body);
    }
    if (message.camera && !buildScene.placed) {
      orbit.lookat = message.camera.lookat;
      orbit.distance = message.camera.distance_m;
      orbit.azimuth = message.camera.azimuth_deg;
      orbit.elevation = message.camera.elevation_deg;
      buildScene.placed = true;
      placeCamera();
    }
    dirty = true;
  }

  function applyPoses(message) {
    const poses = message.poses;
    if (poses.length !== meshes.length) return;  // shapes of another model: the next scene message follows
    for (let k = 0; k < poses.length; k++) {
      const [x, y, z, qw, qx, qy, qz] = poses[k];
      meshes[k].position.set(x, y, z);
      meshes[k].quaternion.set(qx, qy, qz, qw);
    }
    window.jointctl3d.lastPoseTime = message.t;
    dirty = true;
  }

  window.addEventListener("jointctl:scene", (event) => buildScene(event.detail));
  if (window.jointctlPage && window.jointctlPage.scene) buildScene(window.jointctlPage.scene);  // came before this loaded
  window.addEventListener("jointctl:poses", (event) => applyPoses(event.detail));

  // Orbit with the mouse, zoom with the wheel.
  let drag = null;
  renderer.domElement.addEventListener("pointerdown", (event) => {
    drag = { x: event.clientX, y: event.clientY, azimuth: orbit.azimuth, elevation: orbit.elevation };
    renderer.domElement.setPointerCapture(event.pointerId);
  });
  renderer.domElement.addEventListener("pointermove", (event) => {
    if (!drag) return;
    orbit.azimuth = drag.azimuth - 0.4 * (event.clientX - drag.x);
    orbit.elevation = Math.max(-89, Math.min(89, drag.elevation + 0.4 * (event.clientY - drag.y)));
    placeCamera();
  });
  renderer.domElement.addEventListener("pointerup", () => { drag = null; });
  renderer.domElement.addEventListener("wheel", (event) => {
    event.preventDefault();
    orbit.distance = Math.max(0.2, Math.min(100, orbit.distance * Math.exp(0.001 * event.deltaY)));
    placeCamera();
  }, { passive: false });

  function draw() {
    if (dirty) {
      renderer.render(scene, camera);
      frames += 1;
      dirty = false;
    }
    requestAnimationFrame(draw);
  }

  window.jointctl3d = {
    lastPoseTime: null,
    get frames() { return frames; },
    get orbit() { return Object.assign({}, orbit); },
    bodies: () => labels.slice(),
    // The canvas pixel (column, row; row 0 at the top) where world point (x, y, z) [m] is drawn.
    project(x, y, z) {
      const v = new THREE.Vector3(x, y, z).project(camera);
      const size = renderer.getSize(new THREE.Vector2());
      return [(v.x + 1) / 2 * size.x, (1 - v.y) / 2 * size.y];
    },
    // Where the first shape of body ``name`` is now, in the world [m].
    position(name) {
      const k = labels.indexOf(name);
      return k < 0 ? null : meshes[k].position.toArray();
    },
  };

  window.addEventListener("resize", resize);
  resize();
  placeCamera();
  requestAnimationFrame(draw);
}
