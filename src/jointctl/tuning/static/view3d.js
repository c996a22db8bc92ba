// jointctl tuning page: the 3D view. The server sends the world's visible shapes ("scene": MuJoCo
// geoms, z up, sizes as MuJoCo gives them, colours from the model) and their poses ("poses", 30 per second
// of loop time); three.js draws them under a sky, on a grid floor (0.1 m squares, 1 m lines) with the
// world's axes (x red, y green, z blue, 0.6 m), with shadows. The camera frames the robot and any
// objects (their bounds) and follows them: when any of them leaves the view (a dropped weight falling
// in) or they shrink to a small part of it, it glides to frame them again (it stands still otherwise, so
// motion is seen against a fixed view), until the wheel zooms by hand; Fit frames them again. Drag to orbit. window.jointctl3d is read by the browser tests.
import * as THREE from "./vendor/three.module.js";

// ?view3d=0 leaves the view out (to compare the page's cost with and without it; the tests of the plots and
// panels leave it out, as its software WebGL competes with the served robot's loop for the CPU).
const box = document.getElementById("view3d");
if (new URLSearchParams(location.search).get("view3d") === "0") {
  box.closest(".view").hidden = true;
} else {
  start();
}

function start() {
  const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
  renderer.setPixelRatio(1);
  renderer.shadowMap.enabled = true;
  renderer.shadowMap.type = THREE.PCFShadowMap;
  box.appendChild(renderer.domElement);
  const scene = new THREE.Scene();
  scene.background = skyTexture();
  scene.add(new THREE.HemisphereLight(0xeaf4ff, 0x8a8272, 1.4));
  const sun = new THREE.DirectionalLight(0xffffff, 1.8);
  sun.position.set(3, -4, 8);
  sun.castShadow = true;
  sun.shadow.mapSize.set(1024, 1024);
  scene.add(sun, sun.target);
  // The floor's grid (three's grid lies in x-z: turned into MuJoCo's x-y) and the world's axes.
  const grid = new THREE.Group();
  const fine = new THREE.GridHelper(10, 50, 0x8d99a3, 0x8d99a3);
  const coarse = new THREE.GridHelper(10, 10, 0x37474f, 0x37474f);
  for (const g of [fine, coarse]) { g.rotation.x = Math.PI / 2; g.material.transparent = true; g.material.opacity = 0.7; grid.add(g); }
  grid.position.z = 0.001;  // above the floor's own plane
  const axes = new THREE.AxesHelper(0.6);
  axes.position.z = 0.002;
  scene.add(grid, axes);
  const camera = new THREE.PerspectiveCamera(40, 1, 0.02, 200);
  camera.up.set(0, 0, 1);  // MuJoCo's z up
  const orbit = { lookat: [0, 0, 1], distance: 5, azimuth: 90, elevation: -20 };  // MuJoCo's free camera, degrees
  let meshes = [];
  let labels = [];
  let frames = 0;
  let dirty = true;
  let follow = true;  // keep the robot and the objects framed (see the top), until the wheel zooms
  let goal = null;  // the framing the camera glides to: {lookat, distance}
  let refits = 0;

  function skyTexture() {
    const canvas = document.createElement("canvas");
    canvas.width = 2;
    canvas.height = 256;
    const ctx = canvas.getContext("2d");
    const gradient = ctx.createLinearGradient(0, 0, 0, 256);
    gradient.addColorStop(0, "#7fa8d1");
    gradient.addColorStop(0.6, "#cfe0ee");
    gradient.addColorStop(1, "#f3f6f8");
    ctx.fillStyle = gradient;
    ctx.fillRect(0, 0, 2, 256);
    const texture = new THREE.CanvasTexture(canvas);
    texture.colorSpace = THREE.SRGBColorSpace;
    return texture;
  }

  // The bounds of everything but the floor (planes), in the world [m].
  function bounds() {
    const all = new THREE.Box3();
    for (const mesh of meshes) if (!mesh.userData.plane) all.union(new THREE.Box3().setFromObject(mesh));
    return all;
  }

  // Look at the bounds' centre from the orbit's direction, at the distance that fits their sphere into
  // the narrower of the view's angles (a tenth to spare), the bounds grown by a fifth of their
  // largest side first: room for the joints to move without leaving the view; the sun's shadow box around them.
  function fit(glide) {
    const b = bounds();
    if (b.isEmpty()) return;
    refits += 1;
    const size = b.getSize(new THREE.Vector3());
    b.expandByScalar(0.2 * Math.max(size.x, size.y, size.z));
    const sphere = b.getBoundingSphere(new THREE.Sphere());
    const radius = Math.max(sphere.radius, 0.05);
    const vertical = THREE.MathUtils.degToRad(camera.fov) / 2;
    const horizontal = Math.atan(Math.tan(vertical) * camera.aspect);
    const target = { lookat: sphere.center.toArray(), distance: 1.1 * radius / Math.sin(Math.min(vertical, horizontal)) };
    if (glide) goal = target;
    else { goal = null; orbit.lookat = target.lookat; orbit.distance = target.distance; }
    const shadow = sun.shadow.camera, reach = radius + 0.5;
    sun.target.position.copy(sphere.center);
    sun.position.copy(sphere.center).add(new THREE.Vector3(3, -4, 8).normalize().multiplyScalar(reach + 5));
    Object.assign(shadow, { left: -reach, right: reach, top: reach, bottom: -reach, near: 0.1, far: 2 * reach + 10 });
    shadow.updateProjectionMatrix();
    placeCamera();
  }

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
    const width = Math.max(200, box.clientWidth), height = Math.max(150, box.clientHeight);
    renderer.setSize(width, height, true);
    camera.aspect = width / height;
    camera.updateProjectionMatrix();
    if (follow) fit(false);
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
      mesh.userData.plane = g.type === "plane";
      mesh.castShadow = !mesh.userData.plane;
      mesh.receiveShadow = true;
      scene.add(mesh);
      meshes.push(mesh);
      labels.push(g.body);
    }
    if (message.camera && !buildScene.placed) {
      // The robot's video camera gives the side it is seen from; somewhat from above, to see the floor.
      orbit.azimuth = message.camera.azimuth_deg;
      orbit.elevation = Math.min(message.camera.elevation_deg, -20);
      buildScene.placed = true;
    }
    placed = false;  // framed at the first poses (the shapes are where the poses put them)
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
    if (!placed) { fit(false); placed = true; } else if (follow && !goal && !framed()) fit(true);
    dirty = true;
  }

  // Whether the bounds are drawn inside the view and fill at least a third of its width or height.
  function framed() {
    const [left, top, right, bottom, width, height] = window.jointctl3d.drawnBounds();
    const inside = left >= 0 && right <= width && top >= 0 && bottom <= height;
    return inside && (right - left > width / 3 || bottom - top > height / 3);
  }

  // A tenth of the way to the goal each frame: about a third of a second at 60 frames a second.
  function glide() {
    if (!goal) return;
    const to = new THREE.Vector3(...goal.lookat), at = new THREE.Vector3(...orbit.lookat).lerp(to, 0.12);
    orbit.lookat = at.toArray();
    orbit.distance += 0.12 * (goal.distance - orbit.distance);
    if (at.distanceTo(to) < 1e-3 && Math.abs(goal.distance - orbit.distance) < 1e-3 * goal.distance) {
      orbit.lookat = goal.lookat;
      orbit.distance = goal.distance;
      goal = null;
    }
    placeCamera();
  }
  let placed = false;

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
    follow = false;
    goal = null;
    orbit.distance = Math.max(0.2, Math.min(100, orbit.distance * Math.exp(0.001 * event.deltaY)));
    placeCamera();
  }, { passive: false });

  function draw() {
    glide();
    if (dirty) {
      renderer.render(scene, camera);
      frames += 1;
      dirty = false;
    }
    requestAnimationFrame(draw);
  }

  document.getElementById("view-fit").addEventListener("click", () => { follow = true; fit(false); });

  window.jointctl3d = {
    lastPoseTime: null,
    get following() { return follow; },
    get refits() { return refits; },
    // Where the bounds of the robot and the objects are drawn: [left, top, right, bottom] in canvas pixels.
    drawnBounds() {
      const b = bounds(), size = renderer.getSize(new THREE.Vector2());
      let left = Infinity, top = Infinity, right = -Infinity, bottom = -Infinity;
      for (const x of [b.min.x, b.max.x]) for (const y of [b.min.y, b.max.y]) for (const z of [b.min.z, b.max.z]) {
        const v = new THREE.Vector3(x, y, z).project(camera);
        const px = (v.x + 1) / 2 * size.x, py = (1 - v.y) / 2 * size.y;
        left = Math.min(left, px); right = Math.max(right, px); top = Math.min(top, py); bottom = Math.max(bottom, py);
      }
      return [left, top, right, bottom, size.x, size.y];
    },
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
