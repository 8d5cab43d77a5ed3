// The settings panel: one control per RenderSettings field, built from the gateway's schema of
// the proto (clients/web/README.md, SettingField) with the choices the server offers and the
// labels, docs and ranges of the server's settings table (ServerInfo.choices.settings), in
// collapsible sections (groupSettings), showing the effective settings of each frame and the
// server's notes on fields it changed.
import { el } from './dom.js';
import { ANIMATION_SETTINGS, tidy } from './animation.js';

// Fields the panel leaves out: the viewport drives width and height, and the Animation section
// (animation.js) owns the animation's fields, so no two controls fight over one.
const HIDDEN_SETTINGS = new Set(['width', 'height', ...ANIMATION_SETTINGS]);

/** Whether the settings panel has a control for a RenderSettings field of this name. */
export function inPanel(name) {
  return !HIDDEN_SETTINGS.has(name);
}

/**
 * The panel's sections, in order. A setting goes to the section that lists it (in the listed
 * order), else to the first section whose `match` fits its name (a field a newer server adds:
 * "ssao_bias" joins Post), else to "Other", so nothing the server offers is lost. `open`:
 * whether the section starts unfolded.
 */
export const SETTING_SECTIONS = [
  {
    id: 'image', title: 'Image', open: true,
    names: ['aa', 'samples', 'vis_mlaa_coverage', 'exposure_mode', 'exposure_ev', 'tonemapper'],
    match: /^(aa_|vis_mlaa|exposure|tonemap)/,
  },
  {
    id: 'lighting', title: 'Lighting', open: true,
    names: ['scene_lights', 'ibl', 'synthetic_lights', 'light_seed', 'light_radius_min',
      'light_radius_max', 'lights_animated', 'light_time'],
    match: /^(lights?_|ibl|synthetic_)/,
  },
  {
    id: 'shadows', title: 'Shadows', open: false,
    names: ['shadows', 'shadow_lights', 'shadow_atlas_size', 'shadow_cache'],
    match: /^shadow/,
  },
  {
    id: 'post', title: 'Post-processing', open: false,
    names: ['ssao', 'ssao_strength', 'ssao_radius', 'ssao_half_res', 'bloom', 'bloom_strength'],
    match: /^(ssao|bloom|post_(?!stage)|vignette|grain|sharpen)/,
  },
  {
    id: 'encoding', title: 'Encoding', open: false,
    names: ['jpeg_quality', 'jpeg_444'],
    match: /^(jpeg|png|webp|encod|chroma)/,
  },
  {
    id: 'pipeline', title: 'Pipeline and debug', open: false,
    names: ['pipeline', 'post_stage', 'culling', 'light_culling', 'light_binning', 'tile_size',
      'tile_depth_mask', 'debug_view', 'pass_timing'],
    match: /^(pipeline|post_stage|cull|tile_|debug)|_(culling|binning)$/,
  },
];
export const OTHER_SECTION = { id: 'other', title: 'Other', open: false };

/**
 * Groups setting names into the panel's sections: [{id, title, open, names}] in section
 * order, empty sections left out, unknown names last under "Other" in the order given.
 * Pure (node --test).
 */
export function groupSettings(names) {
  const listed = new Map();
  for (const section of SETTING_SECTIONS) for (const n of section.names) listed.set(n, section.id);
  const members = new Map([...SETTING_SECTIONS, OTHER_SECTION].map((s) => [s.id, []]));
  const given = new Set(names);
  for (const section of SETTING_SECTIONS) {
    for (const n of section.names) if (given.has(n)) members.get(section.id).push(n);
  }
  for (const n of names) {
    if (listed.has(n)) continue;
    const section = SETTING_SECTIONS.find((s) => s.match.test(n)) ?? OTHER_SECTION;
    members.get(section.id).push(n);
  }
  return [...SETTING_SECTIONS, OTHER_SECTION]
    .filter((s) => members.get(s.id).length > 0)
    .map(({ id, title, open }) => ({ id, title, open, names: members.get(id) }));
}

/**
 * The unit in a range text when it names one: "0..1e6 world units, 0 = auto" -> "world units";
 * "" for "0..1", "1, 2, 4 or 8" or "a power of two, 512..8192".
 */
export function rangeUnit(range) {
  const m = /^\s*[-+\d.e]+\s*\.\.\s*[-+\d.e]+\s+([a-z][a-z ]*[a-z])\s*(,|$)/i.exec(String(range ?? ''));
  return m ? m[1] : '';
}

/**
 * A label in the panel's one style: sentence case (the server's label, or the field's name
 * with spaces), with the unit in parentheses when the range names one and the label does not.
 */
export function settingLabel(label, range) {
  const text = String(label).trim();
  const sentence = text.charAt(0).toUpperCase() + text.slice(1);
  const unit = rangeUnit(range);
  return unit && !sentence.includes('(') ? `${sentence} (${unit})` : sentence;
}

/**
 * What the server's settings table says about a field (ServerInfo.choices.settings: label, doc,
 * range), as {label, doc, min, max}, the label in the panel's style (settingLabel). A server
 * without the table (an older tesserad) gives no range and the field's name as its label.
 */
export function settingSpec(name, info) {
  const spec = (info?.choices?.settings ?? []).find((s) => s.name === name);
  const out = { label: settingLabel(spec?.label || name.replace(/_/g, ' '), spec?.range), doc: spec?.doc ?? '' };
  if (spec && (spec.type === 'uint' || spec.type === 'float')) {
    out.min = Number(spec.min);
    out.max = Number(spec.max);
    if (spec.range) out.doc = out.doc ? `${out.doc} (${spec.range})` : spec.range;
  }
  // The server may cap the synthetic lights below the table's range (its --max_synthetic_lights).
  const cap = Number(info?.limits?.max_synthetic_lights);
  if (name === 'synthetic_lights' && cap > 0) out.max = Math.min(out.max ?? cap, cap);
  return out;
}

/** "AA_VIS_MLAA" -> "vis_mlaa": the prefix the enum's values share, removed; lower case. */
function enumLabel(value, allValues = []) {
  const names = allValues.filter((v) => !v.endsWith('_UNSPECIFIED'));
  let prefix = '';
  if (names.length > 1) {
    const parts = names.map((n) => n.split('_'));
    let i = 0;
    while (parts.every((p) => p.length > i + 1 && p[i] === parts[0][i])) i++;
    prefix = i > 0 ? `${parts[0].slice(0, i).join('_')}_` : '';
  } else if (value.includes('_')) {
    prefix = value.slice(0, value.indexOf('_') + 1);
  }
  return (value.startsWith(prefix) ? value.slice(prefix.length) : value).toLowerCase();
}

export class SettingsPanel {
  /**
   * `onChange(name, value)` is called with each valid change the user makes; `guard(fn, context)`
   * wraps the controls' handlers (the page's error banner).
   */
  constructor(root, notesList, onChange, guard = (fn) => fn) {
    this.root = root;
    this.notesList = notesList;
    this.onChange = onChange;
    this.guard = guard;
    this.controls = new Map();  // field name -> {element, row, read(), write(value)}
    this.sections = new Map();  // section id -> {details, names}
  }

  /**
   * One control per schema field (width/height excepted), showing the server's defaults, in
   * sections (<details>, groupSettings) ordered as the server's settings table. `extra` maps a
   * section id to nodes that go first in it (the page's own resolution field in "Image").
   */
  build(schema, info, extra = {}) {
    this.controls.clear();
    this.sections = new Map();
    const rows = new Map();  // field name -> its row
    for (const field of schema) {
      if (!inPanel(field.name)) continue;
      const control = this.#control(field, info);
      if (!control) continue;
      control.element.id = `setting-${field.name}`;
      const spec = settingSpec(field.name, info);
      const label = el('label', spec.label);
      label.htmlFor = control.element.id;
      if (spec.doc) label.title = control.element.title = spec.doc;
      control.row = el('div', undefined, 'field');
      control.row.append(label, control.element);
      rows.set(field.name, control.row);
      this.controls.set(field.name, control);
      const initial = info?.default_settings?.[field.name];
      if (initial !== undefined) control.write(initial);
      control.element.addEventListener('change', this.guard(() => {
        const value = control.read();
        if (value !== undefined) this.onChange(field.name, value);  // else the control says why
      }, 'Could not apply the setting'));
    }
    // The server's table order keeps a switch next to its parameters (ssao, ssao_radius, ...).
    const table = (info?.choices?.settings ?? []).map((s) => s.name);
    const rank = (name) => (table.includes(name) ? table.indexOf(name) : table.length);
    const names = [...rows.keys()].sort((a, b) => rank(a) - rank(b));
    const groups = groupSettings(names);
    for (const id of Object.keys(extra)) {
      if (groups.some((g) => g.id === id)) continue;
      const known = SETTING_SECTIONS.find((s) => s.id === id) ?? { id, title: id, open: true };
      groups.unshift({ ...known, names: [] });
    }
    const nodes = groups.map((group) => {
      const details = el('details', undefined, 'group');
      details.id = `group-${group.id}`;
      details.open = group.open;
      const body = el('div', undefined, 'group-body');
      body.append(...(extra[group.id] ?? []), ...group.names.map((n) => rows.get(n)));
      details.append(el('summary', group.title), body);
      this.sections.set(group.id, { details, names: group.names });
      return details;
    });
    if (rows.size === 0) nodes.push(el('p', 'The server offers no settings.', 'note'));
    this.root.replaceChildren(...nodes);
  }

  #control(field, info) {
    if (field.type === 'enum') {
      const values = field.values ?? [];
      const offered = field.choices?.length
        ? field.choices : values.filter((v) => !v.endsWith('_UNSPECIFIED'));
      return selectControl(offered.map((v) => [v, enumLabel(v, values)]), String);
    }
    if (field.type === 'bool') {
      const input = el('input');
      input.type = 'checkbox';
      const write = (v) => { input.checked = Boolean(v); };
      return { element: input, read: () => input.checked, write };
    }
    const integer = /int/.test(field.type);  // uint32 (and any other integer type)
    if (!integer && !/float|double/.test(field.type)) return null;  // unknown: no control
    // Numbers the server offers as a list (samples, tile_size) get a select.
    const listed = field.choices?.length ? field.choices : info?.choices?.[field.name] ?? [];
    const choices = listed.map(Number).filter(Number.isFinite);
    if (choices.length > 0) return selectControl(choices.map((n) => [String(n), String(n)]), Number);
    return numberControl(settingSpec(field.name, info), integer, field.type.startsWith('u'));
  }

  /**
   * Shows a frame's effective settings, except in controls the user is editing (a number
   * being typed) or changed after the event this frame reflects; and the frame's notes.
   */
  reflect(frame, pendingFields) {
    const settings = frame.settings ?? {};
    const eventId = Number(frame.event_id ?? 0);
    for (const [name, control] of this.controls) {
      if (!(name in settings)) continue;
      const pending = pendingFields.get(name);
      if (pending !== undefined && eventId < pending) continue;
      pendingFields.delete(name);
      if (document.activeElement === control.element && control.element.type === 'number') continue;
      control.write(settings[name]);
    }
    const notes = frame.notes ?? [];
    const noted = new Set(notes.map((n) => n.field));
    for (const [name, { row }] of this.controls) row.classList.toggle('clamped', noted.has(name));
    // A folded section with a changed field says so on its title.
    for (const { details, names } of this.sections.values()) {
      details.classList.toggle('clamped', names.some((n) => noted.has(n)));
    }
    this.notesList.replaceChildren(...notes.map((n) => el('li', `${n.field}: ${n.message}`)));
    this.notesList.hidden = notes.length === 0;
  }
}

/** A <select> of [value, label] options; a value the server reports that is not listed is added. */
function selectControl(options, parse) {
  const select = el('select');
  for (const [value, label] of options) select.append(new Option(label, value));
  return {
    element: select,
    read: () => parse(select.value),
    write(v) {
      const value = String(v);
      if (![...select.options].some((o) => o.value === value)) {
        select.append(new Option(enumLabel(value), value));
      }
      select.value = value;
    },
  };
}

/**
 * The value of a number input when it is a number in [min, max] (whole when `integer`);
 * else undefined, with the input marked invalid and the reason shown.
 */
export function validNumber(input, { min = -Infinity, max = Infinity }, integer) {
  const v = Number(input.value);
  let problem = '';
  if (input.value.trim() === '' || !Number.isFinite(v)) problem = 'Enter a number.';
  else if (integer && !Number.isInteger(v)) problem = 'Enter a whole number.';
  else if (v < min) problem = `Enter ${min} or more.`;
  else if (v > max) problem = `Enter ${max} or less.`;
  input.setCustomValidity(problem);
  input.setAttribute('aria-invalid', String(problem !== ''));
  if (problem) {
    input.reportValidity();
    return undefined;
  }
  return v;
}

/**
 * A number input that refuses (and marks) values out of range, or not whole when `integer`;
 * `unsigned` types start at 0.
 */
function numberControl({ min, max }, integer, unsigned = false) {
  if (unsigned && min === undefined) min = 0;
  const input = el('input');
  input.type = 'number';
  if (min !== undefined) input.min = String(min);
  if (max !== undefined) input.max = String(max);
  input.step = integer ? '1' : 'any';
  return {
    element: input,
    read: () => validNumber(input, { min, max }, integer),
    write(v) {
      input.value = String(tidy(Number(v)));
      input.setCustomValidity('');
      input.setAttribute('aria-invalid', 'false');
    },
  };
}
