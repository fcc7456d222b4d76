// The user's own account (#/account): change the password (the other sessions end) and the list of open
// sessions, each of the others with an "End" button.  Refusals come from the server already in the UI's
// language (api.js sends Accept-Language), so they are shown as they are.

import { api } from "../api.js";
import { h, clear, field, alertBox, errorText, dateTime } from "../dom.js";
import { t } from "../i18n.js";

function passwordForm() {
  const input = (name, autocomplete) => h("input", { type: "password", name, autocomplete, required: true });
  const [curField, current] = field(t("account.current_password"), input("current_password", "current-password"));
  const [newField, next] = field(t("account.new_password"), input("new_password", "new-password"),
    t("account.password_hint"));
  const [repField, repeat] = field(t("account.repeat_password"), input("repeat_password", "new-password"));
  const message = h("div", { class: "form-message", "aria-live": "polite" });
  const submit = h("button", { type: "submit" }, t("account.change_password"));
  const form = h("form", { class: "card", id: "password-form" }, h("h2", {}, t("account.password_title")),
    curField, newField, repField, message, submit);
  form.addEventListener("submit", async (e) => {
    e.preventDefault();
    clear(message);
    if (next.value !== repeat.value) {
      message.append(alertBox(t("account.passwords_differ")));
      return;
    }
    submit.disabled = true;
    try {
      const answer = await api("POST", "/auth/password",
        { json: { current_password: current.value, new_password: next.value } });
      form.reset();
      message.append(alertBox(t("account.password_changed", { n: answer.ended_sessions }), "info"));
      form.dispatchEvent(new CustomEvent("sessions-changed", { bubbles: true }));
    } catch (err) {
      message.append(alertBox(errorText(err)));
    } finally {
      submit.disabled = false;
    }
  });
  return form;
}

function sessionsCard() {
  const list = h("ul", { class: "sessions", id: "session-list" });
  const message = h("div", { class: "form-message", "aria-live": "polite" });
  const endOthers = h("button", { type: "button", class: "secondary" }, t("account.end_others"));
  const card = h("section", { class: "card" }, h("h2", {}, t("account.sessions_title")), list, message, endOthers);

  async function load() {
    clear(list);
    let rows;
    try {
      rows = await api("GET", "/auth/sessions");
    } catch (err) {
      message.append(alertBox(errorText(err)));
      return;
    }
    if (!card.isConnected) return;
    for (const s of rows) {
      const end = h("button", { type: "button", class: "secondary small" }, t("account.end_session"));
      end.addEventListener("click", async () => {
        clear(message);
        try {
          await api("DELETE", `/auth/sessions/${s.id}`);
          load();
        } catch (err) {
          message.append(alertBox(errorText(err)));
        }
      });
      list.append(h("li", {},
        h("span", {}, t("account.session_line", { opened: dateTime(s.created_at), client: s.client || "–" })),
        h("span", { class: "muted" }, ` ${s.user_agent || ""} `),
        s.current ? h("strong", {}, t("account.this_session")) : end));
    }
  }

  endOthers.addEventListener("click", async () => {
    clear(message);
    try {
      const answer = await api("POST", "/auth/end-other-sessions");
      message.append(alertBox(t("account.sessions_ended", { n: answer.ended_sessions }), "info"));
      load();
    } catch (err) {
      message.append(alertBox(errorText(err)));
    }
  });
  card.addEventListener("sessions-changed", load);
  queueMicrotask(load);
  return [card, load];
}

/** The account page of the logged-in user. */
export function accountView() {
  const [sessions, reload] = sessionsCard();
  const form = passwordForm();
  form.addEventListener("sessions-changed", reload);
  return h("section", { class: "view narrow" }, h("h1", {}, t("account.title")), form, sessions);
}
