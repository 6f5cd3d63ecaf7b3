// The app's 3D view (a gr.HTML component's js_on_load, after web/mannequin.js): `element` is the component,
// `props.value` is {glb: URL, audio: URL} (or empty), `watch` re-runs `show` when the value changes.

function show(element, value) {
  const canvas = element.querySelector("canvas");
  const audio = element.querySelector("audio");
  const status = element.querySelector(".status");
  if (element._canvas !== canvas) {  // first call, or the template was drawn anew
    element._canvas = canvas;
    element._viewer = makeViewer(canvas, audio, status);
    element._shown = null;
  }
  if (!element._viewer || !value || !value.glb) return;
  if (element._shown === value.glb) return;
  element._shown = value.glb;
  status.textContent = "loading the animation…";
  if (value.audio) audio.src = value.audio;
  fetch(value.glb).then((r) => r.arrayBuffer()).then((glb) => {
    const clip = element._viewer.upload(glb);
    canvas.dataset.face = String(clip.face ? clip.face.targets.length : 0);  // for the tests: the face's targets
    canvas.dataset.loaded = value.glb;
    status.textContent = "drag to turn, scroll to zoom; press play to hear the speech with it";
  }).catch((error) => { status.textContent = `the 3D view could not load the animation (${error})`; });
}

show(element, props.value);
watch("value", () => show(element, props.value));
