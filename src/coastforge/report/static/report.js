(function () {
  var lb = document.getElementById('lightbox'), lbi = lb.querySelector('img');
  document.querySelectorAll('figure img').forEach(function (im) {
    if (im.closest('.stack') && !im.classList.contains('top')) return;
    im.addEventListener('click', function () { lbi.src = im.src; lb.style.display = 'flex'; });
  });
  lb.addEventListener('click', function () { lb.style.display = 'none'; lbi.removeAttribute('src'); });
  var op = document.getElementById('classmap-opacity'), cm = document.getElementById('classmap-img');
  if (op && cm) op.addEventListener('input', function () { cm.style.opacity = op.value / 100; });
  var data = document.getElementById('glb-data'), el = document.getElementById('viewer');
  if (!data || !el) return;
  if (!window.CoastforgeViewer) { el.textContent = 'The 3D viewer script did not load.'; return; }
  var v;
  try {
    v = window.CoastforgeViewer.show(el, data.textContent.trim(), {height: el.clientHeight || 560});
  } catch (e) {
    el.dataset.error = String(e);
    el.textContent = 'This browser cannot show the 3D preview (WebGL unavailable): ' + e;
    console.warn(e);
    return;
  }
  v.then(function (r) {
    el.dataset.drawnMs = String(Math.round(performance.now()));
    document.querySelectorAll('.vbar button').forEach(function (b) {
      b.addEventListener('click', function () { r.view && r.view(b.dataset.view); });
    });
  }).catch(function (e) { el.dataset.error = String(e); console.error('3D preview: ' + e); });
})();
