// turbinefit view: draws the scene data of turbinefit.view.scene with three.js (the global
// THREE of vendor/three.min.js). World frame z up, metres from the tower base.
(function () {
  'use strict';

  const data = JSON.parse(document.getElementById('turbinefit-data').textContent);
  const api = (window.turbinefitView = { ready: false, error: null, data: data });

  // ---------------------------------------------------------------- helpers
  const TYPES = { float32: Float32Array, uint32: Uint32Array, uint8: Uint8Array };

  function decode(item) {
    const bin = atob(item.b64);
    const bytes = new Uint8Array(bin.length);
    for (let i = 0; i < bin.length; i++) bytes[i] = bin.charCodeAt(i);
    return new TYPES[item.dtype](bytes.buffer);
  }

  function el(tag, attrs, children) {
    const e = document.createElement(tag);
    for (const [k, v] of Object.entries(attrs || {})) {
      if (k === 'text') e.textContent = v;
      else if (k === 'style') e.style.cssText = v;
      else e.setAttribute(k, v);
    }
    for (const c of children || []) e.append(c);
    return e;
  }

  function svg(tag, attrs) {
    const e = document.createElementNS('http://www.w3.org/2000/svg', tag);
    for (const [k, v] of Object.entries(attrs || {})) e.setAttribute(k, v);
    return e;
  }

  function linearColours(srgb) {  // sRGB bytes -> linear floats (three.js's working space)
    const out = new Float32Array(srgb.length);
    for (let i = 0; i < srgb.length; i++) {
      const c = srgb[i] / 255;
      out[i] = c <= 0.04045 ? c / 12.92 : Math.pow((c + 0.055) / 1.055, 2.4);
    }
    return out;
  }

  function fatal(message) {
    api.error = message;
    document.body.append(el('p', { class: 'fatal', text: message }));
    document.documentElement.dataset.ready = 'error';
  }

  const fmt = (x, d) => Number(x).toFixed(d);

  // ---------------------------------------------------------------- renderer and camera
  let renderer;
  try {
    renderer = new THREE.WebGLRenderer({ antialias: true, alpha: true, preserveDrawingBuffer: true });
  } catch (e) {
    fatal('This page needs WebGL, which this browser does not offer (' + e.message + ').');
    return;
  }
  const stage = document.getElementById('stage');
  renderer.setPixelRatio(Math.min(window.devicePixelRatio || 1, 2));
  renderer.setSize(window.innerWidth, window.innerHeight);
  stage.append(renderer.domElement);

  THREE.Object3D.DEFAULT_UP.set(0, 0, 1);
  const scene = new THREE.Scene();
  const view = data.view;
  const radius = Math.max(view.radius, 1);
  const camera = new THREE.PerspectiveCamera(view.fov, window.innerWidth / window.innerHeight,
    Math.max(0.05, radius / 5000), radius * 60);
  camera.up.set(0, 0, 1);
  const controls = new THREE.OrbitControls(camera, renderer.domElement);
  controls.screenSpacePanning = true;
  controls.zoomToCursor = true;

  function resetView() {
    camera.position.fromArray(view.position);
    controls.target.fromArray(view.target);
    controls.update();
  }
  resetView();

  scene.add(new THREE.HemisphereLight(0xffffff, 0x8f8a80, 1.7));
  const sun = new THREE.DirectionalLight(0xffffff, 1.9);
  sun.position.set(-0.45, -0.75, 1.1);
  scene.add(sun);
  const fill = new THREE.DirectionalLight(0xffffff, 0.6);
  fill.position.set(0.6, 0.5, 0.3);
  scene.add(fill);

  // ---------------------------------------------------------------- layers
  const layers = [];

  function addLayer(key, label, colour, objects, visible, swatch) {
    const layer = { key, label, colour, objects, visible, swatch: swatch || 'line' };
    for (const o of objects) { o.visible = visible; scene.add(o); }
    layers.push(layer);
    return layer;
  }

  function setLayer(key, visible) {
    const layer = layers.find((l) => l.key === key);
    if (!layer) return false;
    layer.visible = visible;
    for (const o of layer.objects) o.visible = visible;
    if (layer.onChange) layer.onChange(visible);
    const box = document.querySelector('input[data-layer="' + key + '"]');
    if (box) box.checked = visible;
    requestRender();
    return true;
  }

  function lineMaterial(colour, opacity) {
    return new THREE.LineBasicMaterial({ color: colour, transparent: opacity < 1, opacity: opacity });
  }

  function segments(positions, pairs, colour, opacity) {
    const g = new THREE.BufferGeometry();
    g.setAttribute('position', new THREE.BufferAttribute(positions, 3));
    g.setIndex(pairs);
    return new THREE.LineSegments(g, lineMaterial(colour, opacity));
  }

  function polyline(positions, colour, opacity) {
    const g = new THREE.BufferGeometry();
    g.setAttribute('position', new THREE.BufferAttribute(positions, 3));
    return new THREE.Line(g, lineMaterial(colour, opacity));
  }

  const dotTexture = (() => {  // round dots rather than squares
    const c = document.createElement('canvas');
    c.width = c.height = 64;
    const g = c.getContext('2d');
    g.fillStyle = '#fff';
    g.beginPath();
    g.arc(32, 32, 30, 0, 2 * Math.PI);
    g.fill();
    return new THREE.CanvasTexture(c);
  })();

  function points(positions, colour, size) {
    const g = new THREE.BufferGeometry();
    g.setAttribute('position', new THREE.BufferAttribute(positions, 3));
    return new THREE.Points(g, new THREE.PointsMaterial({
      color: colour, size: size, sizeAttenuation: false, map: dotTexture, alphaTest: 0.5 }));
  }

  const FRUSTUM_EDGES = [0, 1, 0, 2, 0, 3, 0, 4, 1, 2, 2, 3, 3, 4, 4, 1];

  function frustumPairs(count) {
    const pairs = new Array(count * FRUSTUM_EDGES.length);
    for (let m = 0; m < count; m++) {
      for (let e = 0; e < FRUSTUM_EDGES.length; e++) pairs[m * 16 + e] = 5 * m + FRUSTUM_EDGES[e];
    }
    return pairs;
  }

  // the fitted turbine: solid, coloured by coverage when given
  const material = new THREE.MeshStandardMaterial({ vertexColors: true, roughness: 0.55, metalness: 0.0 });
  const meshes = [];
  for (const part of data.turbine.parts) {
    const g = new THREE.BufferGeometry();
    g.setAttribute('position', new THREE.BufferAttribute(decode(part.position), 3));
    g.setAttribute('normal', new THREE.BufferAttribute(decode(part.normal), 3));
    g.setIndex(new THREE.BufferAttribute(decode(part.index), 1));
    const plain = linearColours(decode(part.plain));
    const covered = part.coverage ? linearColours(decode(part.coverage)) : null;
    g.setAttribute('color', new THREE.BufferAttribute(Float32Array.from(covered || plain), 3));
    const mesh = new THREE.Mesh(g, material);
    mesh.userData = { plain: plain, covered: covered };
    meshes.push(mesh);
  }
  const turbineLayer = addLayer('turbine', 'fitted turbine', '#d8dadc', meshes, true, 'solid');
  if (data.coverage) {
    const cov = addLayer('coverage', 'coverage colours on the turbine', null, [], true, 'gradient');
    cov.onChange = (on) => {
      for (const m of meshes) {
        const c = m.geometry.getAttribute('color');
        c.array.set(on && m.userData.covered ? m.userData.covered : m.userData.plain);
        c.needsUpdate = true;
      }
    };
  }
  // cameras: path through every keyframe, frusta at the keyframes shown
  const kf = data.keyframes;
  const shownIndex = new Map(kf.shown.map((k, j) => [k, j]));
  const pickables = [];
  const sets = {};
  for (const c of data.cameras) {
    const pos = decode(c.positions);
    const fr = decode(c.frusta);
    const main = c.name === 'optimised';  // drawn last, on top, with a dot per keyframe
    const objects = [polyline(pos, c.colour, main ? 0.9 : 0.6)];
    if (main) objects.push(points(pos, c.colour, 2.5));
    if (fr.length) objects.push(segments(fr, frustumPairs(fr.length / 15), c.colour, main ? 0.95 : 0.45));
    for (const o of objects) o.renderOrder = main ? 2 : 1;
    const layer = addLayer('cameras_' + c.name, c.label, c.colour, objects, true);
    sets[c.name] = { positions: pos, frusta: fr, layer: layer, colour: c.colour, label: c.label };
    pickables.push({ kind: 'keyframe', set: c.name, positions: pos, layer: layer });
  }

  const skeletonPairs = [].concat(...data.lines);
  const fitted = decode(data.turbine.skeleton);
  addLayer('fitted_skeleton', 'fitted skeleton (the model)', data.turbine.colour,
    [segments(fitted, skeletonPairs, data.turbine.colour, 1), points(fitted, data.turbine.colour, 6)], false);
  for (const s of data.skeletons) {
    const p = decode(s.points);
    addLayer('skeleton_' + s.name, s.label, s.colour,
      [segments(p, skeletonPairs, s.colour, 1), points(p, s.colour, 6)], true);
  }

  // planned path
  let planFrusta = null;
  if (data.plan) {
    const p = data.plan;
    const path = decode(p.path);
    planFrusta = decode(p.frusta);
    const centres = new Float32Array(planFrusta.length / 5);
    for (let m = 0; m < planFrusta.length / 15; m++) centres.set(planFrusta.subarray(15 * m, 15 * m + 3), 3 * m);
    const objects = [polyline(path, p.colour, 1), points(path, p.colour, 4)];
    if (planFrusta.length) objects.push(segments(planFrusta, frustumPairs(planFrusta.length / 15), p.colour, 0.8));
    const layer = addLayer('plan', 'planned path (' + p.labels.length + ' photos, ' + fmt(p.length, 0) + ' m)',
      p.colour, objects, true);
    pickables.push({ kind: 'plan', set: 'plan', positions: centres, layer: layer });
  }

  // ground grid
  const gridStep = radius > 400 ? 50 : radius > 150 ? 20 : 10;
  const cells = Math.max(4, Math.ceil((2.4 * radius) / gridStep));
  const grid = new THREE.GridHelper(cells * gridStep, cells, 0xaab4be, 0xc9d0d6);
  grid.rotation.x = Math.PI / 2;
  grid.position.set(Math.round(view.target[0] / gridStep) * gridStep,
    Math.round(view.target[1] / gridStep) * gridStep, 0);
  addLayer('grid', 'ground grid (' + gridStep + ' m squares)', '#aab4be', [grid], true);

  // selection marker: a dot of constant size, seen through whatever hides it
  const SELECTED = 0xffa000;
  const marker = points(new Float32Array(3), SELECTED, 13);
  marker.material.depthTest = false;
  marker.renderOrder = 10;
  marker.visible = false;
  scene.add(marker);
  let highlight = null;

  // ---------------------------------------------------------------- labels
  const labelBox = document.getElementById('labels');
  const labels = data.turbine.labels.map((l) => {
    const e = el('div', { class: 'label', text: l.text });
    labelBox.append(e);
    return { at: new THREE.Vector3().fromArray(l.at), el: e, layer: turbineLayer };
  });

  function updateLabels() {
    const w = window.innerWidth, h = window.innerHeight;
    const v = new THREE.Vector3();
    for (const l of labels) {
      v.copy(l.at).project(camera);
      const on = l.layer.visible && v.z < 1 && Math.abs(v.x) < 1.2 && Math.abs(v.y) < 1.2;
      l.el.style.display = on ? '' : 'none';
      if (on) {
        l.el.style.left = ((v.x + 1) / 2) * w + 'px';
        l.el.style.top = ((1 - v.y) / 2) * h + 'px';
      }
    }
  }

  // ---------------------------------------------------------------- rendering
  let pending = false;
  function render() {
    renderer.render(scene, camera);
    updateLabels();
  }
  function requestRender() {
    if (pending) return;
    pending = true;
    requestAnimationFrame(() => { pending = false; render(); });
  }
  controls.addEventListener('change', requestRender);
  window.addEventListener('resize', () => {
    camera.aspect = window.innerWidth / window.innerHeight;
    camera.updateProjectionMatrix();
    renderer.setSize(window.innerWidth, window.innerHeight);
    requestRender();
  });

  // ---------------------------------------------------------------- header and legend
  function buildHeader() {
    const box = document.getElementById('header');
    box.append(el('h1', { text: data.title }));
    const rows = [];
    if (data.verdict) {
      rows.push(el('tr', {}, [el('td', { text: 'verdict' }),
        el('td', {}, [el('span', { class: 'verdict ' + data.verdict, text: data.verdict })])]));
    }
    for (const [k, v] of data.facts) rows.push(el('tr', {}, [el('td', { text: k }), el('td', { text: v })]));
    box.append(el('table', {}, rows));
    if (data.notes.length) box.append(el('ul', { class: 'notes' }, data.notes.map((n) => el('li', { text: n }))));
  }

  function swatch(layer) {
    if (layer.swatch === 'gradient' && data.coverage) {
      return el('span', { class: 'swatch solid', style: 'background:linear-gradient(90deg,' + data.coverage.stops.join(',') + ')' });
    }
    return el('span', { class: 'swatch' + (layer.swatch === 'solid' ? ' solid' : ''), style: 'background:' + layer.colour });
  }

  function coverageScale() {
    const c = data.coverage;
    const pos = (x) => (100 * Math.log(x / c.lo)) / Math.log(c.hi / c.lo);
    const bar = el('div', { class: 'bar', style: 'background:linear-gradient(90deg,' + c.stops.join(',') + ')' }, [
      el('span', { class: 'mark', style: 'left:calc(' + pos(c.max_gsd) + '% - 1px)' })]);
    const ticks = el('div', { class: 'ticks' }, [el('span', { text: fmt(c.lo, 2) }),
      el('span', { text: '\u2264 ' + c.max_gsd + ' mm/px (red mark)' }), el('span', { text: fmt(c.hi, 1) })]);
    const blades = Object.keys(c.table).filter((p) => p.startsWith('blade'));
    const sideNames = blades.length ? Object.keys(c.table[blades[0]]) : [];
    const abbrev = (s) => s.split('_').map((w) => w[0].toUpperCase()).join('');
    const head = el('tr', {}, [el('th', { text: 'covered %' })].concat(sideNames.map((s) => el('th', { text: abbrev(s), title: s.replace('_', ' ') }))));
    const rows = blades.map((b) => el('tr', {}, [el('td', { text: b.replace('_', ' ') })].concat(
      sideNames.map((s) => el('td', { text: fmt(100 * c.table[b][s][0], 0) })))));
    const parts = [el('div', { class: 'small', text: 'best resolution reached, mm per pixel (' + c.source + '); grey: never seen' }), bar, ticks,
      el('table', { class: 'cov' }, [head].concat(rows))];
    if (c.table.tower) {
      parts.push(el('div', { class: 'small', text: 'tower: ' + Object.entries(c.table.tower).map(([s, v]) => s + ' ' + fmt(100 * v[0], 0)).join(', ') + ' %' }));
    }
    parts.push(el('div', { class: 'small', text: 'LE leading edge, PS pressure side, TE trailing edge, SS suction side' }));
    return el('div', { class: 'scale' }, parts);
  }

  function buildLegend() {
    const box = document.getElementById('legend');
    box.append(el('h2', { text: 'Layers' }));
    for (const layer of layers) {
      const input = el('input', { type: 'checkbox', 'data-layer': layer.key });
      input.checked = layer.visible;
      input.addEventListener('change', () => setLayer(layer.key, input.checked));
      box.append(el('label', {}, [input, swatch(layer), el('span', { text: layer.label })]));
    }
    if (data.coverage) box.append(coverageScale());
    const photos = data.photos.length;
    box.append(el('div', { class: 'small', text: 'Click a camera' + (photos ? ' (' + photos + ' of ' + kf.count + ' have their photo)' : '') +
      '. Metres from the tower base, z up.' }));
  }

  // ---------------------------------------------------------------- picking
  const tooltip = document.getElementById('tooltip');

  function pick(x, y) {
    const w = window.innerWidth, h = window.innerHeight;
    const v = new THREE.Vector3();
    let best = null, bestD = 14 * 14;
    for (const p of pickables) {
      if (!p.layer.visible) continue;
      const a = p.positions;
      for (let i = 0; i < a.length / 3; i++) {
        v.set(a[3 * i], a[3 * i + 1], a[3 * i + 2]).project(camera);
        if (v.z > 1 || v.z < -1) continue;
        const dx = ((v.x + 1) / 2) * w - x, dy = ((1 - v.y) / 2) * h - y;
        const d = dx * dx + dy * dy;
        if (d < bestD) { bestD = d; best = { kind: p.kind, set: p.set, index: i }; }
      }
    }
    return best;
  }

  function describe(hit) {
    if (hit.kind === 'plan') return 'planned photo ' + (hit.index + 1) + ': ' + data.plan.labels[hit.index];
    const t = kf.timestamps[hit.index];
    return 'keyframe ' + hit.index + ' \u00b7 t = ' + fmt(t, 2) + ' s' + (photoIndex.has(hit.index) ? ' \u00b7 photo' : '');
  }

  let down = null;
  renderer.domElement.addEventListener('pointerdown', (e) => { down = [e.clientX, e.clientY]; });
  renderer.domElement.addEventListener('pointerup', (e) => {
    if (!down || Math.hypot(e.clientX - down[0], e.clientY - down[1]) > 4) return;
    const hit = pick(e.clientX, e.clientY);
    if (hit && hit.kind === 'keyframe') select(hit.index, hit.set);
    else if (hit && hit.kind === 'plan') selectPlan(hit.index);
  });
  let hoverPending = false;
  renderer.domElement.addEventListener('pointermove', (e) => {
    if (hoverPending || e.buttons) return;
    hoverPending = true;
    requestAnimationFrame(() => {
      hoverPending = false;
      const hit = pick(e.clientX, e.clientY);
      renderer.domElement.style.cursor = hit ? 'pointer' : '';
      tooltip.hidden = !hit;
      if (hit) {
        tooltip.textContent = describe(hit);
        tooltip.style.left = e.clientX + 14 + 'px';
        tooltip.style.top = e.clientY + 10 + 'px';
      }
    });
  });
  renderer.domElement.addEventListener('pointerleave', () => { tooltip.hidden = true; });

  // ---------------------------------------------------------------- photo panel
  const photos = data.photos.slice().sort((a, b) => a.keyframe - b.keyframe);
  const photoIndex = new Map(photos.map((p, i) => [p.keyframe, i]));
  const overlayOn = {};
  const panel = document.getElementById('photo');
  let selected = null;

  function setHighlight(frusta, index, colour) {
    if (highlight) { scene.remove(highlight); highlight.geometry.dispose(); highlight = null; }
    if (frusta && index !== null) {
      highlight = segments(frusta.slice(15 * index, 15 * index + 15), frustumPairs(1), colour, 1);
      highlight.material.depthTest = false;
      highlight.renderOrder = 10;
      scene.add(highlight);
    }
  }

  function position(set, k) {
    const p = sets[set].positions;
    return new THREE.Vector3(p[3 * k], p[3 * k + 1], p[3 * k + 2]);
  }

  function overlaySvg(photo) {
    const box = svg('svg', { viewBox: '-0.5 -0.5 ' + photo.width + ' ' + photo.height, preserveAspectRatio: 'none' });
    const r = Math.max(1.5, photo.width / 140);
    for (const o of photo.overlays) {
      if (overlayOn[o.name] === false) continue;
      const g = svg('g', {});
      for (const line of o.lines) {
        const pts = [];
        for (let i = 0; i < line.length; i += 2) pts.push(line[i] + ',' + line[i + 1]);
        const d = pts.join(' ');
        g.append(svg('polyline', { points: d, fill: 'none', stroke: '#000', 'stroke-opacity': 0.55, 'stroke-width': 3.5, 'vector-effect': 'non-scaling-stroke', 'stroke-linejoin': 'round' }));
        g.append(svg('polyline', { points: d, fill: 'none', stroke: o.colour, 'stroke-width': 1.8, 'vector-effect': 'non-scaling-stroke', 'stroke-linejoin': 'round' }));
      }
      for (const [u, v] of o.points) {
        g.append(svg('circle', { cx: u, cy: v, r: r, fill: o.colour, stroke: '#000', 'stroke-width': 0.8, 'vector-effect': 'non-scaling-stroke' }));
      }
      box.append(g);
    }
    return box;
  }

  function showPanel(title, body, nav) {
    panel.replaceChildren();
    const buttons = [];
    if (nav) {
      const prev = el('button', { text: '\u25c0', title: 'previous photo (\u2190)' });
      prev.addEventListener('click', () => step(-1));
      const next = el('button', { text: '\u25b6', title: 'next photo (\u2192)' });
      next.addEventListener('click', () => step(1));
      buttons.push(prev, next);
    }
    const close = el('button', { text: '\u00d7', title: 'close (Esc)' });
    close.addEventListener('click', closePanel);
    buttons.push(close);
    panel.append(el('div', { class: 'bar-buttons' }, [el('h2', { text: title, style: 'margin:0' }), el('span', {}, buttons)]));
    for (const b of body) panel.append(b);
    panel.hidden = false;
  }

  function closePanel() {
    panel.hidden = true;
    selected = null;
    marker.visible = false;
    setHighlight(null, null);
    requestRender();
  }

  function select(k, set) {
    if (!(k >= 0 && k < kf.count)) return false;
    set = set && sets[set] ? set : Object.keys(sets)[0];
    selected = k;
    marker.geometry.getAttribute('position').array.set(position(set, k).toArray());
    marker.geometry.getAttribute('position').needsUpdate = true;
    marker.geometry.computeBoundingSphere();
    marker.visible = true;
    setHighlight(shownIndex.has(k) ? sets[set].frusta : null, shownIndex.has(k) ? shownIndex.get(k) : null, SELECTED);
    const body = [];
    const i = photoIndex.get(k);
    if (i !== undefined) {
      const photo = photos[i];
      const img = el('img', { src: photo.src, alt: 'photo of keyframe ' + k, width: photo.width, height: photo.height });
      body.push(el('div', { class: 'frame' }, [img, overlaySvg(photo)]));
      const keys = photo.overlays.map((o) => {
        const input = el('input', { type: 'checkbox' });
        input.checked = overlayOn[o.name] !== false;
        input.addEventListener('change', () => { overlayOn[o.name] = input.checked; select(k, set); });
        return el('label', {}, [input, el('span', { class: 'swatch', style: 'background:' + o.colour }), el('span', { text: o.label + ' reprojected' })]);
      });
      body.push(el('div', { class: 'keys' }, keys));
    } else {
      const near = nearestPhoto(k);
      const note = el('div', { class: 'nophoto', text: photos.length
        ? 'No photo embedded for this keyframe. ' : 'No photos are embedded in this page.' });
      if (near !== null) {
        const go = el('button', { text: 'show keyframe ' + near + ', the nearest with one' });
        go.addEventListener('click', () => select(near, set));
        note.append(go);
      }
      body.push(el('div', { class: 'frame' }, [note]));
    }
    const rows = [['time', fmt(kf.timestamps[k], 3) + ' s']];
    const opt = sets.optimised ? position('optimised', k) : null;
    if (opt) rows.push(['optimised position', [opt.x, opt.y, opt.z].map((x) => fmt(x, 2)).join(', ') + ' m']);
    if (opt && sets.initial) rows.push(['moved from the initial pose', fmt(opt.distanceTo(position('initial', k)), 3) + ' m']);
    if (opt && sets.ground_truth) {
      const gt = position('ground_truth', k);
      rows.push(['position error, optimised', fmt(opt.distanceTo(gt), 3) + ' m']);
      if (sets.initial) rows.push(['position error, initial', fmt(position('initial', k).distanceTo(gt), 3) + ' m']);
    }
    body.push(el('table', {}, rows.map(([a, b]) => el('tr', {}, [el('td', { text: a }), el('td', { text: b })]))));
    showPanel('Keyframe ' + k + ' of ' + kf.count, body, photos.length > 0);
    requestRender();
    return true;
  }

  function selectPlan(m) {
    selected = null;
    const fr = planFrusta;
    marker.geometry.getAttribute('position').array.set(fr.subarray(15 * m, 15 * m + 3));
    marker.geometry.getAttribute('position').needsUpdate = true;
    marker.geometry.computeBoundingSphere();
    marker.visible = true;
    setHighlight(fr, m, SELECTED);
    showPanel('Planned photo ' + (m + 1) + ' of ' + data.plan.labels.length,
      [el('p', { text: data.plan.labels[m] }), el('p', { class: 'small', text: 'from ' + data.plan.source })], false);
    requestRender();
  }

  function nearestPhoto(k) {
    let best = null;
    for (const p of photos) if (best === null || Math.abs(p.keyframe - k) < Math.abs(best - k)) best = p.keyframe;
    return best;
  }

  function step(dir) {
    if (!photos.length) return;
    const k = selected === null ? (dir > 0 ? -1 : kf.count) : selected;
    let next = null;
    for (const p of photos) {
      if (dir > 0 && p.keyframe > k) { next = p.keyframe; break; }
      if (dir < 0 && p.keyframe < k) next = p.keyframe;
    }
    if (next !== null) select(next);
  }

  window.addEventListener('keydown', (e) => {
    if (e.target && e.target.tagName === 'INPUT') return;
    if (e.key === 'ArrowRight') step(1);
    else if (e.key === 'ArrowLeft') step(-1);
    else if (e.key === 'Escape') closePanel();
    else if (e.key === 'r' || e.key === 'R') { resetView(); requestRender(); }
  });

  // ---------------------------------------------------------------- start
  buildHeader();
  buildLegend();
  render();
  Object.assign(api, {
    select: select, setLayer: setLayer, resetView: () => { resetView(); render(); },
    layers: () => layers.map((l) => ({ key: l.key, label: l.label, visible: l.visible })),
    render: render,
    screenOf: (set, k) => {  // where camera k of a set is drawn [CSS px], null if not in view
      if (!sets[set] || !(k >= 0 && k < kf.count)) return null;
      const v = position(set, k).project(camera);
      if (v.z > 1 || Math.abs(v.x) > 1 || Math.abs(v.y) > 1) return null;
      return [((v.x + 1) / 2) * window.innerWidth, ((1 - v.y) / 2) * window.innerHeight];
    },
    selected: () => selected,
  });
  requestAnimationFrame(() => {
    api.ready = true;
    api.readyMs = performance.now();
    document.documentElement.dataset.ready = 'true';
  });
})();
