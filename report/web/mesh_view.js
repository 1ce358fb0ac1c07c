// objscan's 3-D mesh view: a scene mesh drawn with three.js (r111, loaded before this script),
// orbit / pan / zoom with the mouse (OrbitControls), hypotheses painted in their rank colours, a
// segment highlighted, and picking of the vertex under the pointer. Shared by report.html
// (inlined) and `objscan view` (served as /assets/mesh_view.js). The mesh arrives in the binary
// form report/include/objscan/report/mesh_view.h describes ("OSVM").
(function () {
  "use strict";

  // core/palette.h's kRankPalette, which objscan writes ahead of this script (report::meshViewJs):
  // a colour names a rank in every picture, page and report.
  var PALETTE = OBJSCAN_RANK_PALETTE;
  var HIGHLIGHT = [255, 215, 0];
  var GREY = 190;

  function rankColour(rank) { return PALETTE[(Math.max(rank, 1) - 1) % PALETTE.length]; }

  // Throws an Error saying what is wrong with a buffer that is not a mesh of this form.
  function decode(buffer) {
    if (!(buffer instanceof ArrayBuffer) || buffer.byteLength < 20) {
      throw new Error("the mesh is empty or cut short");
    }
    var head = new DataView(buffer, 0, 20);
    var magic = String.fromCharCode(head.getUint8(0), head.getUint8(1), head.getUint8(2),
                                    head.getUint8(3));
    if (magic !== "OSVM") throw new Error("not an objscan mesh (no OSVM header)");
    if (head.getUint32(4, true) !== 1) throw new Error("a mesh of an unknown version");
    var n = head.getUint32(8, true), t = head.getUint32(12, true);
    var colours = (head.getUint32(16, true) & 1) === 1;
    var at = 20;
    var need = at + n * 12 + (colours ? n * 4 : 0) + (n + (n % 2)) * 2 + t * 12;
    if (buffer.byteLength !== need) {
      throw new Error("the mesh is " + buffer.byteLength + " bytes, not the " + need +
                      " its header announces");
    }
    var mesh = {vertices: n, triangles: t};
    mesh.positions = new Float32Array(buffer, at, n * 3); at += n * 12;
    mesh.colours = colours ? new Uint8Array(buffer, at, n * 4) : null;
    if (colours) at += n * 4;
    mesh.ranks = new Uint16Array(buffer, at, n); at += (n + (n % 2)) * 2;
    mesh.indices = new Uint32Array(buffer, at, t * 3);
    for (var i = 0; i < mesh.indices.length; ++i) {
      if (mesh.indices[i] >= n) throw new Error("a triangle names a vertex outside the mesh");
    }
    return mesh;
  }

  function base64ToBuffer(text) {
    var bytes = atob(text), out = new Uint8Array(bytes.length);
    for (var i = 0; i < bytes.length; ++i) out[i] = bytes.charCodeAt(i);
    return out.buffer;
  }

  // A view of `mesh` (decode's result) in `container` (an element with a size). `camera`
  // (optional): where to start, {position, forward, up, fov_y_deg} (mesh_view.h's
  // viewCameraJson); without it, from behind and above the scene.
  function MeshView(container, mesh, camera) {
    if (typeof THREE === "undefined") throw new Error("three.js did not load");
    this.container = container;
    this.mesh = mesh;
    this.mode = mesh.colours ? "colour" : "shading";
    this.start = camera || null;
    this.showRanks = true;
    // The pictures paint the best few (render --top); the rest only when asked (setPaintAll).
    this.paintTop = Infinity;
    this.paintAll = false;
    this.highlight = null;
    this.renderer = new THREE.WebGLRenderer({antialias: true, preserveDrawingBuffer: true});
    this.renderer.setPixelRatio(window.devicePixelRatio || 1);
    this.renderer.setClearColor(0xf4f5f7, 1);
    container.appendChild(this.renderer.domElement);

    var g = new THREE.BufferGeometry();
    var set = (g.setAttribute || g.addAttribute).bind(g);
    set("position", new THREE.BufferAttribute(mesh.positions, 3));
    this.colourArray = new Uint8Array(mesh.vertices * 3);
    this.colourAttribute = new THREE.BufferAttribute(this.colourArray, 3, true);
    set("color", this.colourAttribute);
    g.setIndex(new THREE.BufferAttribute(mesh.indices, 1));
    g.computeVertexNormals();
    g.computeBoundingSphere();
    this.geometry = g;
    var material = new THREE.MeshLambertMaterial({
      vertexColors: THREE.VertexColors !== undefined ? THREE.VertexColors : true,
      side: THREE.DoubleSide});
    this.object = new THREE.Mesh(g, material);

    this.scene = new THREE.Scene();
    this.scene.add(this.object);
    this.scene.add(new THREE.AmbientLight(0xffffff, 0.55));
    this.camera = new THREE.PerspectiveCamera(50, 1, 0.01, 1000);
    var light = new THREE.DirectionalLight(0xffffff, 0.6);
    light.position.set(0.3, -0.5, -1);  // from the viewer's side, a little above
    this.camera.add(light);
    this.scene.add(this.camera);
    this.controls = new THREE.OrbitControls(this.camera, this.renderer.domElement);
    this.controls.enableDamping = false;
    var self = this;
    this.controls.addEventListener("change", function () { self.render(); });
    this.resetCamera();
    this.paint();
    this.resize();
    this.onResize = function () { self.resize(); };
    window.addEventListener("resize", this.onResize);
  }

  // Lets the view go: its listener, controls, GPU buffers and WebGL context, and its canvas.
  MeshView.prototype.dispose = function () {
    window.removeEventListener("resize", this.onResize);
    this.controls.dispose();
    this.geometry.dispose();
    this.object.material.dispose();
    this.renderer.dispose();
    if (this.renderer.forceContextLoss) this.renderer.forceContextLoss();
    var canvas = this.renderer.domElement;
    if (canvas.parentNode) canvas.parentNode.removeChild(canvas);
  };

  // Looks at the whole mesh from behind and above its sensor's first view (objscan's scenes have
  // y down and z forward, as the camera that made them).
  MeshView.prototype.resetCamera = function () {
    var s = this.geometry.boundingSphere;
    var r = Math.max(s.radius, 1e-3);
    this.camera.near = r / 100;
    this.camera.far = r * 100;
    var c = this.start;
    if (c && c.position && c.forward && c.up) {
      // The pictures' camera; it turns about the point of its axis nearest the scene's centre.
      var p = new THREE.Vector3().fromArray(c.position);
      var f = new THREE.Vector3().fromArray(c.forward).normalize();
      var d = Math.max(s.center.clone().sub(p).dot(f), r / 10);
      this.camera.up.fromArray(c.up);
      this.camera.position.copy(p);
      this.camera.fov = c.fov_y_deg || 50;
      this.controls.target.copy(p.clone().add(f.multiplyScalar(d)));
    } else {
      this.camera.up.set(0, -1, 0);
      this.camera.position.set(s.center.x, s.center.y - 0.7 * r, s.center.z - 1.4 * r);
      this.controls.target.copy(s.center);
    }
    this.camera.updateProjectionMatrix();
    this.controls.update();
  };

  // Points the camera at the centre of `vertices` (preview vertex indices), keeping its distance.
  MeshView.prototype.focus = function (vertices) {
    if (!vertices || vertices.length === 0) return;
    var p = this.mesh.positions, c = new THREE.Vector3();
    for (var i = 0; i < vertices.length; ++i) {
      c.x += p[3 * vertices[i]]; c.y += p[3 * vertices[i] + 1]; c.z += p[3 * vertices[i] + 2];
    }
    c.multiplyScalar(1 / vertices.length);
    var shift = c.clone().sub(this.controls.target);
    this.controls.target.add(shift);
    this.camera.position.add(shift);
    this.controls.update();
  };

  MeshView.prototype.setMode = function (mode) { this.mode = mode; this.paint(); };
  MeshView.prototype.setShowRanks = function (on) { this.showRanks = on; this.paint(); };
  // Paint ranks 1 to `top` only, as the pictures do; setPaintAll(true) paints every hypothesis.
  MeshView.prototype.setPaintTop = function (top) { this.paintTop = top; this.paint(); };
  MeshView.prototype.setPaintAll = function (on) { this.paintAll = on; this.paint(); };
  MeshView.prototype.painted = function (rank) {
    return this.showRanks && rank > 0 && (this.paintAll || rank <= this.paintTop);
  };
  // `vertices`: preview vertex indices (a typed array or array) to draw in the highlight colour;
  // null for none.
  MeshView.prototype.setHighlight = function (vertices) { this.highlight = vertices; this.paint(); };

  MeshView.prototype.paint = function () {
    var m = this.mesh, out = this.colourArray, useColour = this.mode === "colour" && m.colours;
    for (var v = 0; v < m.vertices; ++v) {
      var r = GREY, g = GREY, b = GREY;
      if (useColour) { r = m.colours[4 * v]; g = m.colours[4 * v + 1]; b = m.colours[4 * v + 2]; }
      var rank = m.ranks[v];
      if (this.painted(rank)) {
        var c = rankColour(rank);
        r = 0.35 * r + 0.65 * c[0]; g = 0.35 * g + 0.65 * c[1]; b = 0.35 * b + 0.65 * c[2];
      } else if (this.highlight) {
        r *= 0.75; g *= 0.75; b *= 0.75;  // the rest recedes while a segment is shown
      }
      out[3 * v] = r; out[3 * v + 1] = g; out[3 * v + 2] = b;
    }
    if (this.highlight) {
      for (var i = 0; i < this.highlight.length; ++i) {
        var h = this.highlight[i];
        if (h < m.vertices) {
          out[3 * h] = HIGHLIGHT[0]; out[3 * h + 1] = HIGHLIGHT[1]; out[3 * h + 2] = HIGHLIGHT[2];
        }
      }
    }
    this.colourAttribute.needsUpdate = true;
    this.render();
  };

  MeshView.prototype.resize = function () {
    var w = Math.max(this.container.clientWidth, 1), h = Math.max(this.container.clientHeight, 1);
    this.renderer.setSize(w, h);
    this.camera.aspect = w / h;
    this.camera.updateProjectionMatrix();
    this.render();
  };

  MeshView.prototype.render = function () {
    this.renderer.render(this.scene, this.camera);
    this.container.setAttribute("data-rendered", String(
        (Number(this.container.getAttribute("data-rendered")) || 0) + 1));
  };

  // The preview vertex under the page point (clientX, clientY), or -1.
  MeshView.prototype.pick = function (clientX, clientY) {
    var box = this.renderer.domElement.getBoundingClientRect();
    var ndc = new THREE.Vector2(((clientX - box.left) / box.width) * 2 - 1,
                                -((clientY - box.top) / box.height) * 2 + 1);
    var ray = new THREE.Raycaster();
    ray.setFromCamera(ndc, this.camera);
    var hits = ray.intersectObject(this.object);
    if (hits.length === 0 || !hits[0].face) return -1;
    var f = hits[0].face, p = hits[0].point, pos = this.mesh.positions, best = -1, bestD = Infinity;
    [f.a, f.b, f.c].forEach(function (v) {
      var dx = pos[3 * v] - p.x, dy = pos[3 * v + 1] - p.y, dz = pos[3 * v + 2] - p.z;
      var d = dx * dx + dy * dy + dz * dz;
      if (d < bestD) { bestD = d; best = v; }
    });
    return best;
  };

  window.ObjscanMeshView = {decode: decode, base64ToBuffer: base64ToBuffer, MeshView: MeshView,
                            rankColour: rankColour};
})();
