// ChakaMo browser UI: start-up, login, header and hash routing.
//
// Single page, no build step: plain ES modules served from /static.  Routes (hash, so the server only has
// to serve index.html): #/login, #/patients, #/patients/7, #/sessions/3/wizard, #/sessions/3/record (recording
// from the sensors over Bluetooth), #/sessions/3[?analysis_id=5], #/account (password change, open sessions),
// #/admin/users|tokens|audit (admins: views/admin.js).
// Each route renders into a fresh <section> put in <main>; a view's timers and async answers check that its
// section is still in the page (isConnected) before touching it, so leaving a page stops its polling.
// Start: GET /auth/me tells whether the browser session cookie is still valid (then the CSRF token comes
// back with it); otherwise the login form is shown and the requested route is kept for after login.

import { api, setCsrf, onUnauthorized } from "./api.js";
import { h, clear, field, alertBox, errorText } from "./dom.js";
import { t, LANGUAGES, initialLanguage, setLanguage, lang, translateStatic } from "./i18n.js";
import { patientsView, patientView } from "./views/patients.js";
import { wizardView } from "./views/wizard.js";
import { resultsView } from "./views/results.js";
import { accountView } from "./views/account.js";
import { adminView } from "./views/admin.js";
import { recordView } from "./views/record.js";

const state = { user: null, wanted: null };
const main = document.getElementById("main");

// -------------------------------------------------------------------------------------------- routing
const ROUTES = [
  [/^#\/patients\/?$/, () => patientsView()],
  [/^#\/patients\/(\d+)$/, (m) => patientView(Number(m[1]))],
  [/^#\/sessions\/(\d+)\/wizard$/, (m) => wizardView(Number(m[1]))],
  [/^#\/sessions\/(\d+)\/record$/, (m) => recordView(Number(m[1]))],
  [/^#\/sessions\/(\d+)$/, (m, query) => resultsView(Number(m[1]), query)],
  [/^#\/account$/, () => accountView()],
  [/^#\/admin\/?$/, () => adminView("users")],
  [/^#\/admin\/(users|tokens|audit)$/, (m) => adminView(m[1])],
];

/** Whether the logged-in user may change data (read_only users only look). */
export function canEdit() {
  return Boolean(state.user) && state.user.role !== "read_only";
}

/** The logged-in user (`GET /auth/me`'s user: id, email, name, role, clinic), or null. */
export function currentUser() {
  return state.user;
}

/** Whether the logged-in user is a clinic admin (who may erase patients and sessions). */
export function isAdmin() {
  return Boolean(state.user) && state.user.role === "admin";
}

/** Go to `hash` (re-renders even when it is the current one). */
export function navigate(hash) {
  if (location.hash === hash) render();
  else location.hash = hash;
}

function render() {
  const [path, qs] = (location.hash || "#/patients").split("?");
  if (!state.user) {
    if (path !== "#/login") state.wanted = location.hash || "#/patients";
    showView(loginView());
    return;
  }
  if (path === "#/login" || path === "#" || path === "") {
    navigate("#/patients");
    return;
  }
  for (const [re, make] of ROUTES) {
    const m = re.exec(path);
    if (m) {
      showView(make(m, new URLSearchParams(qs || "")));
      return;
    }
  }
  showView(h("section", { class: "view" }, h("h1", {}, t("error.not_found_title")),
    h("p", {}, t("error.not_found")), h("p", {}, h("a", { href: "#/patients" }, t("nav.patients")))));
}

let titleObserver = null;

function showView(section) {
  clear(main).append(section);
  // views fill in their <h1> when their data arrives: the window title follows it
  const setTitle = () => {
    const heading = section.querySelector("h1");
    document.title = heading ? `${heading.textContent} · ChakaMo` : "ChakaMo";
  };
  setTitle();
  if (titleObserver) titleObserver.disconnect();
  titleObserver = new MutationObserver(setTitle);
  titleObserver.observe(section, { childList: true, subtree: true });
  main.focus({ preventScroll: true });
  window.scrollTo(0, 0);
  updateNav();
}

// --------------------------------------------------------------------------------------------- header
function updateNav() {
  const nav = document.getElementById("nav");
  const who = document.getElementById("who");
  clear(nav);
  clear(who);
  if (!state.user) return;
  const current = (location.hash || "").startsWith("#/patients");
  nav.append(h("a", { href: "#/patients", "aria-current": current ? "page" : null }, t("nav.patients")));
  if (isAdmin()) {
    const admin = (location.hash || "").startsWith("#/admin");
    nav.append(h("a", { href: "#/admin/users", "aria-current": admin ? "page" : null, id: "nav-admin" }, t("nav.admin")));
  }
  const u = state.user;
  // the clinic's name is ellipsised below 1100 px: its title keeps it whole (as the user's line, which can be long too)
  const clinicName = (u.clinic && u.clinic.name) || "";
  const userLine = `${u.name || u.email} · ${t(`role.${u.role}`)}`;
  who.append(h("span", { class: "clinic", title: clinicName || null }, clinicName),
    h("span", { class: "user", title: userLine }, userLine),
    h("a", { href: "#/account", class: "account-link" }, t("nav.account")),
    h("button", { type: "button", class: "secondary small", onclick: logout }, t("nav.logout")));
}

function languageSwitcher() {
  const select = document.getElementById("lang");
  clear(select);
  for (const code of LANGUAGES) {
    select.append(h("option", { value: code, selected: code === lang() }, t(`lang.${code}`)));
  }
  select.value = lang();
}

async function changeLanguage(code) {
  await setLanguage(code);
  translateStatic();
  languageSwitcher();
  render();
}

// ---------------------------------------------------------------------------------------------- login
function loginView() {
  const [emailField, email] = field(t("login.email"),
    h("input", { type: "email", name: "email", autocomplete: "username", required: true }));
  const [passField, password] = field(t("login.password"),
    h("input", { type: "password", name: "password", autocomplete: "current-password", required: true }));
  // an email may have accounts in several clinics (one per clinic): then the clinic's name says which one
  const [clinicField, clinic] = field(t("login.clinic"),
    h("input", { type: "text", name: "clinic", autocomplete: "organization", maxlength: 200 }));
  const message = h("div", { class: "form-message", "aria-live": "polite" });
  const submit = h("button", { type: "submit" }, t("login.submit"));
  const form = h("form", { class: "card login" }, emailField, passField, clinicField, message, submit);
  form.addEventListener("submit", async (e) => {
    e.preventDefault();
    clear(message);
    submit.disabled = true;
    try {
      const answer = await api("POST", "/auth/login", { json: { email: email.value.trim(), password: password.value,
        clinic: clinic.value.trim() || null } });
      state.user = answer.user;
      setCsrf(answer.csrf_token);
      const next = state.wanted && !state.wanted.startsWith("#/login") ? state.wanted : "#/patients";
      state.wanted = null;
      navigate(next);
    } catch (err) {
      message.append(alertBox(err.status === 401 ? t("login.failed") : errorText(err)));
      password.select();
    } finally {
      submit.disabled = false;
    }
  });
  queueMicrotask(() => email.focus());
  return h("section", { class: "view narrow" }, h("h1", {}, t("login.title")), h("p", { class: "lead" }, t("login.lead")), form);
}

async function logout() {
  try {
    await api("POST", "/auth/logout");
  } catch (_) { /* already logged out: fine */ }
  state.user = null;
  setCsrf(null);
  navigate("#/login");
}

// ---------------------------------------------------------------------------------------------- start
onUnauthorized(() => {
  if (!state.user) return;
  state.user = null;
  setCsrf(null);
  state.wanted = location.hash;
  render();
});

async function start() {
  await setLanguage(initialLanguage(), { remember: false });
  translateStatic();
  languageSwitcher();
  document.getElementById("lang").addEventListener("change", (e) => changeLanguage(e.target.value));
  try {
    const me = await api("GET", "/auth/me");
    state.user = me.user;
    setCsrf(me.csrf_token);
  } catch (_) {
    state.user = null;
  }
  window.addEventListener("hashchange", render);
  render();
  document.body.classList.add("ready");
}

start().catch((err) => {
  clear(main).append(alertBox(`ChakaMo: ${err.message}`));
});
