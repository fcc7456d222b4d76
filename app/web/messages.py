"""Every message of login, passwords and accounts a user can cause, in Spanish, English and Portuguese.

``CATALOGUE[code][lang]`` is a :meth:`str.format` template filled from the refusal's ``params``; a message says
what was wrong and what to do.  :func:`refusal` builds the ``HTTPException`` of a code in the language the
request asks for (``Accept-Language``; the browser UI sends its own choice, see ``static/api.js``; English when
none of es/en/pt is asked) and names the code in the ``X-ChakaMo-Code`` header, so a program can tell refusals
apart without parsing sentences.  The ``cli.*`` entries are ``chakamo``'s words in ``--lang`` (:mod:`app.cli.language`),
and the ``settings.*`` ones the refusals of the environment (:data:`app.settings.MESSAGES`, kept there).
"""

from __future__ import annotations

import string
from typing import TYPE_CHECKING

from fastapi import HTTPException

from app.settings import MESSAGES as SETTINGS_MESSAGES

if TYPE_CHECKING:
    from fastapi import Request

LANGUAGES = ("es", "en", "pt")
DEFAULT = "en"
CODE_HEADER = "X-ChakaMo-Code"

CATALOGUE: dict[str, dict[str, str]] = {
    "login.wrong": {
        "en": "Wrong email or password (if your email has accounts in several clinics, also give the clinic's "
              "name); try again or ask your clinic admin to reset it.",
        "es": "Correo o contraseña incorrectos (si su correo tiene cuentas en varias clínicas, indique también el "
              "nombre de la clínica); inténtelo de nuevo o pida al administrador de su clínica que la restablezca.",
        "pt": "E-mail ou palavra-passe incorretos (se o seu e-mail tem contas em várias clínicas, indique também o nome da "
              "clínica); tente de novo ou peça ao administrador da sua clínica que a redefina."},
    "login.throttled": {
        "en": "Too many failed logins for this email or from this computer; wait {seconds} s and try again, or ask "
              "your clinic admin to unlock the account.",
        "es": "Demasiados intentos fallidos para este correo o desde este equipo; espere {seconds} s y vuelva a "
              "intentarlo, o pida al administrador de su clínica que desbloquee la cuenta.",
        "pt": "Demasiadas tentativas falhadas para este e-mail ou a partir deste computador; aguarde {seconds} s e "
              "tente de novo, ou peça ao administrador da sua clínica que desbloqueie a conta."},
    "login.too_many_at_once": {
        "en": "Too many logins at once from this computer; wait a second and try again.",
        "es": "Demasiados inicios de sesión a la vez desde este equipo; espere un segundo y vuelva a intentarlo.",
        "pt": "Demasiados inícios de sessão ao mesmo tempo a partir deste computador; aguarde um segundo e tente de novo."},
    "login.busy": {
        "en": "The server is busy checking other logins; try again in a moment.",
        "es": "El servidor está ocupado comprobando otros inicios de sesión; vuelva a intentarlo en un momento.",
        "pt": "O servidor está ocupado a verificar outros inícios de sessão; tente de novo dentro de momentos."},
    "password.too_short": {
        "en": "The password must have at least {min} characters; choose a longer one (a phrase of several words is "
              "easy to remember).",
        "es": "La contraseña debe tener al menos {min} caracteres; elija una más larga (una frase de varias palabras "
              "es fácil de recordar).",
        "pt": "A palavra-passe deve ter pelo menos {min} caracteres; escolha uma mais longa (uma frase de várias palavras é "
              "fácil de lembrar)."},
    "password.pattern": {
        "en": "The password is a simple pattern (a repeated character or group, or a run of the keyboard, the "
              "alphabet or the digits); choose one that is hard to guess.",
        "es": "La contraseña es un patrón simple (un carácter o grupo repetido, o una serie del teclado, del alfabeto "
              "o de los dígitos); elija una difícil de adivinar.",
        "pt": "A palavra-passe é um padrão simples (um carácter ou grupo repetido, ou uma sequência do teclado, do alfabeto "
              "ou dos dígitos); escolha uma difícil de adivinhar."},
    "password.common": {
        "en": "The password is one of the most common passwords (or one with a few digits or symbols added); choose "
              "one that is hard to guess.",
        "es": "La contraseña es una de las más comunes (o una con algunos dígitos o símbolos añadidos); elija una "
              "difícil de adivinar.",
        "pt": "A palavra-passe é uma das mais comuns (ou uma com alguns dígitos ou símbolos acrescentados); escolha uma "
              "difícil de adivinhar."},
    "password.personal": {
        "en": "The password contains your email or your name; choose one that does not.",
        "es": "La contraseña contiene su correo o su nombre; elija una que no los contenga.",
        "pt": "A palavra-passe contém o seu e-mail ou o seu nome; escolha uma que não os contenha."},
    "password.wrong_current": {
        "en": "The current password is wrong; type it again (nothing was changed).",
        "es": "La contraseña actual no es correcta; escríbala de nuevo (no se ha cambiado nada).",
        "pt": "A palavra-passe atual não está correta; escreva-a de novo (nada foi alterado)."},
    "password.busy": {
        "en": "The server is busy checking passwords; try again in a moment (nothing was changed).",
        "es": "El servidor está ocupado comprobando contraseñas; vuelva a intentarlo en un momento (no se ha cambiado "
              "nada).",
        "pt": "O servidor está ocupado a verificar palavras-passe; tente de novo dentro de momentos (nada foi alterado)."},
    # ``chakamo patients|sessions correct|erase`` and ``chakamo retention`` (app/cli/records.py), in --lang
    "cli.set_not_pair": {
        "en": "--set {pair!r} is not FIELD=VALUE; e.g. --set name=\"Ana Pérez\"",
        "es": "--set {pair!r} no es CAMPO=VALOR; p. ej. --set name=\"Ana Pérez\"",
        "pt": "--set {pair!r} não é CAMPO=VALOR; p. ex. --set name=\"Ana Pérez\""},
    "cli.set_field": {
        "en": "{field} cannot be corrected; correct {fields}",
        "es": "{field} no se puede corregir; corrija {fields}",
        "pt": "{field} não pode ser corrigido; corrija {fields}"},
    "cli.set_not_date": {
        "en": "{field}={value!r} is not a date (YYYY-MM-DD); correct the value",
        "es": "{field}={value!r} no es una fecha (AAAA-MM-DD); corrija el valor",
        "pt": "{field}={value!r} não é uma data (AAAA-MM-DD); corrija o valor"},
    "cli.set_not_number": {
        "en": "{field}={value!r} is not a number; correct the value",
        "es": "{field}={value!r} no es un número; corrija el valor",
        "pt": "{field}={value!r} não é um número; corrija o valor"},
    "cli.set_nothing": {
        "en": "nothing to correct; give at least one --set FIELD=VALUE",
        "es": "nada que corregir; indique al menos un --set CAMPO=VALOR",
        "pt": "nada a corrigir; indique pelo menos um --set CAMPO=VALOR"},
    "cli.erase_confirm": {
        "en": "--confirm {confirm!r} is not the patient's external id; repeat it exactly to erase the record and "
              "everything under it for good (nothing was erased)",
        "es": "--confirm {confirm!r} no es el identificador externo del paciente; repítalo exactamente para borrar "
              "el registro y todo lo que contiene para siempre (no se ha borrado nada)",
        "pt": "--confirm {confirm!r} não é o identificador externo do paciente; repita-o exatamente para apagar o "
              "registo e tudo o que contém de vez (nada foi apagado)"},
    "cli.corrected": {
        "en": "{kind} {id}: corrected {fields}",
        "es": "{kind} {id}: corregidos {fields}",
        "pt": "{kind} {id}: corrigidos {fields}"},
    "cli.unchanged": {
        "en": "{kind} {id}: nothing changed",
        "es": "{kind} {id}: no ha cambiado nada",
        "pt": "{kind} {id}: nada foi alterado"},
    # one sentence a kind: the participle agrees with it ("sesión 5 borrada", "sessão 5 apagada")
    "cli.erased_patient": {
        "en": "patient {id} erased: {sessions} session(s), {erased} stored file(s) erased, {kept} kept (another "
              "record has the same content)",
        "es": "paciente {id} borrado: {sessions} sesión(es), {erased} archivo(s) guardado(s) borrado(s), {kept} "
              "conservado(s) (otro registro tiene el mismo contenido)",
        "pt": "paciente {id} apagado: {sessions} sessão(ões), {erased} ficheiro(s) guardado(s) apagado(s), {kept} "
              "mantido(s) (outro registo tem o mesmo conteúdo)"},
    "cli.erased_session": {
        "en": "session {id} erased: {erased} stored file(s) erased, {kept} kept (another record has the same "
              "content)",
        "es": "sesión {id} borrada: {erased} archivo(s) guardado(s) borrado(s), {kept} conservado(s) (otro "
              "registro tiene el mismo contenido)",
        "pt": "sessão {id} apagada: {erased} ficheiro(s) guardado(s) apagado(s), {kept} mantido(s) (outro registo "
              "tem o mesmo conteúdo)"},
    #: the record kinds of ``chakamo patients|sessions``, as the sentences above name them
    "cli.kind_patient": {"en": "patient", "es": "paciente", "pt": "paciente"},
    "cli.kind_session": {"en": "session", "es": "sesión", "pt": "sessão"},
    "cli.retention_off": {
        "en": "the retention policy is off (CHAKAMO_RETENTION_DAYS is 0); give --days N or set "
              "CHAKAMO_RETENTION_DAYS",
        "es": "la política de conservación está desactivada (CHAKAMO_RETENTION_DAYS es 0); indique --days N o "
              "defina CHAKAMO_RETENTION_DAYS",
        "pt": "a política de conservação está desativada (CHAKAMO_RETENTION_DAYS é 0); indique --days N ou "
              "defina CHAKAMO_RETENTION_DAYS"},
    "cli.retention_due": {
        "en": "retention {days} days at {now} UTC: {n} session(s) due (dry run: nothing erased; --apply erases them)",
        "es": "conservación {days} días a las {now} UTC: {n} sesión(es) vencida(s) (simulación: no se ha borrado "
              "nada; --apply las borra)",
        "pt": "conservação {days} dias às {now} UTC: {n} sessão(ões) vencida(s) (simulação: nada foi apagado; "
              "--apply apaga-as)"},
    "cli.retention_erased": {
        "en": "retention {days} days at {now} UTC: {n} session(s) erased",
        "es": "conservación {days} días a las {now} UTC: {n} sesión(es) borrada(s)",
        "pt": "conservação {days} dias às {now} UTC: {n} sessão(ões) apagada(s)"},
    "cli.retention_session": {
        "en": "  session {session} (clinic {clinic}, patient {patient}), last activity {last}",
        "es": "  sesión {session} (clínica {clinic}, paciente {patient}), última actividad {last}",
        "pt": "  sessão {session} (clínica {clinic}, paciente {patient}), última atividade {last}"},
    "cli.retention_files": {
        "en": "{erased} stored file(s) erased, {kept} kept (still referenced), {swept} orphan(s) swept",
        "es": "{erased} archivo(s) guardado(s) borrado(s), {kept} conservado(s) (aún referenciados), {swept} "
              "huérfano(s) eliminado(s)",
        "pt": "{erased} ficheiro(s) guardado(s) apagado(s), {kept} mantido(s) (ainda referenciados), {swept} "
              "órfão(s) eliminado(s)"},
    # ``chakamo process``'s progress lines on stderr (app/cli/session.py), in --lang: the pipeline's stage names
    "cli.stage_read": {"en": "read", "es": "lectura", "pt": "leitura"},
    "cli.stage_accelerometer": {"en": "accelerometer", "es": "acelerómetro", "pt": "acelerómetro"},
    "cli.stage_magnetometer": {"en": "magnetometer", "es": "magnetómetro", "pt": "magnetómetro"},
    "cli.stage_orientation_thigh": {"en": "orientation of the thigh sensor", "es": "orientación del sensor del muslo",
                                    "pt": "orientação do sensor da coxa"},
    "cli.stage_orientation_shank": {"en": "orientation of the shank sensor",
                                    "es": "orientación del sensor de la pierna", "pt": "orientação do sensor da perna"},
    "cli.stage_segments": {"en": "segments", "es": "segmentos", "pt": "segmentos"},
    "cli.stage_knee": {"en": "knee", "es": "rodilla", "pt": "joelho"},
    "cli.stage_task": {"en": "task", "es": "tarea", "pt": "tarefa"},
    "cli.stage_reports": {"en": "reports", "es": "informes", "pt": "relatórios"},
    "cli.stage_write": {"en": "write", "es": "escritura", "pt": "escrita"},
    "cli.stage_done": {"en": "done", "es": "terminado", "pt": "concluído"},
    "cli.stage_right": {"en": "{stage} (right knee)", "es": "{stage} (rodilla derecha)",
                        "pt": "{stage} (joelho direito)"},
    "cli.stage_left": {"en": "{stage} (left knee)", "es": "{stage} (rodilla izquierda)",
                       "pt": "{stage} (joelho esquerdo)"},
    "cli.exclude_cycles": {
        "en": "--exclude-cycles: {item!r} is not a cycle number (e.g. 3) or knee:number (e.g. right:3); correct the "
              "list",
        "es": "--exclude-cycles: {item!r} no es un número de ciclo (p. ej. 3) ni rodilla:número (p. ej. right:3); "
              "corrija la lista",
        "pt": "--exclude-cycles: {item!r} não é um número de ciclo (p. ex. 3) nem joelho:número (p. ex. right:3); "
              "corrija a lista"},
    # ``chakamo tokens`` (app/cli/admin.py), in --lang
    "cli.token_created": {
        "en": "API token for {clinic!r} ({details}). It is shown only now: store it in the hospital system; send it "
              "as 'Authorization: Bearer <token>'.",
        "es": "Token de API para {clinic!r} ({details}). Solo se muestra ahora: guárdelo en el sistema del hospital; "
              "envíelo como 'Authorization: Bearer <token>'.",
        "pt": "Token de API para {clinic!r} ({details}). Só é mostrado agora: guarde-o no sistema do hospital; "
              "envie-o como 'Authorization: Bearer <token>'."},
    "cli.token_scopes": {"en": "scopes {scopes}", "es": "ámbitos {scopes}", "pt": "âmbitos {scopes}"},
    "cli.token_expires": {"en": "expires in {days:g} days", "es": "caduca en {days:g} días",
                          "pt": "expira em {days:g} dias"},
    "cli.token_rotated": {
        "en": "API token {new_id} of {clinic!r} replaces token {id}, which ends {ends}. The new token is shown only "
              "now:",
        "es": "El token de API {new_id} de {clinic!r} sustituye al token {id}, que termina el {ends}. El token nuevo "
              "solo se muestra ahora:",
        "pt": "O token de API {new_id} de {clinic!r} substitui o token {id}, que termina em {ends}. O token novo só "
              "é mostrado agora:"},
    "cli.tokens_none": {
        "en": "no API tokens in {clinic!r}; create one with `chakamo tokens create`",
        "es": "no hay tokens de API en {clinic!r}; cree uno con `chakamo tokens create`",
        "pt": "não há tokens de API em {clinic!r}; crie um com `chakamo tokens create`"},
    #: the columns of ``chakamo tokens list`` (and the word for "every scope"), separated by "|"
    "cli.tokens_columns": {"en": "id|role|created|revoked|expires|scopes|label|all",
                           "es": "id|rol|creado|revocado|caduca|ámbitos|etiqueta|todos",
                           "pt": "id|papel|criado|revogado|expira|âmbitos|rótulo|todos"},
    "cli.token_revoked": {
        "en": "API token {id} of {clinic!r}{label} revoked: the API now answers 401 to it",
        "es": "Token de API {id} de {clinic!r}{label} revocado: la API ahora le responde 401",
        "pt": "Token de API {id} de {clinic!r}{label} revogado: a API agora responde 401 a ele"},
    "cli.token_already_revoked": {
        "en": "API token {id} of {clinic!r}{label} was already revoked on {when}; nothing changed",
        "es": "El token de API {id} de {clinic!r}{label} ya se revocó el {when}; no se ha cambiado nada",
        "pt": "O token de API {id} de {clinic!r}{label} já foi revogado em {when}; nada foi alterado"},
    "cli.token_unknown": {
        "en": "no API token with id {id}; see the ids with `chakamo tokens list --clinic NAME`",
        "es": "no hay ningún token de API con id {id}; vea los ids con `chakamo tokens list --clinic NOMBRE`",
        "pt": "não há nenhum token de API com id {id}; veja os ids com `chakamo tokens list --clinic NOME`"},
    # ``chakamo clinics`` and ``chakamo users`` (app/cli/admin.py), in --lang
    "cli.clinic_created": {
        "en": "clinic {name!r} created (id {id})",
        "es": "clínica {name!r} creada (id {id})",
        "pt": "clínica {name!r} criada (id {id})"},
    "cli.clinic_name_empty": {
        "en": "the clinic name is empty; give a name, e.g. chakamo clinics create \"Clínica Norte\"",
        "es": "el nombre de la clínica está vacío; indique un nombre, p. ej. chakamo clinics create \"Clínica Norte\"",
        "pt": "o nome da clínica está vazio; indique um nome, p. ex. chakamo clinics create \"Clínica Norte\""},
    "cli.clinic_exists": {
        "en": "a clinic named {name!r} already exists; choose another name",
        "es": "ya existe una clínica llamada {name!r}; elija otro nombre",
        "pt": "já existe uma clínica chamada {name!r}; escolha outro nome"},
    "cli.role_unknown": {
        "en": "role {role!r} is unknown; use one of {roles}",
        "es": "el rol {role!r} no existe; use uno de {roles}",
        "pt": "o papel {role!r} não existe; use um de {roles}"},
    "cli.email_invalid": {
        "en": "{email!r} is not an email address; give the user's email",
        "es": "{email!r} no es una dirección de correo; indique el correo del usuario",
        "pt": "{email!r} não é um endereço de e-mail; indique o e-mail do utilizador"},
    "cli.email_taken": {
        "en": "the email {email} already has an account in {clinic!r}; use another email",
        "es": "el correo {email} ya tiene una cuenta en {clinic!r}; use otro correo",
        "pt": "o e-mail {email} já tem uma conta em {clinic!r}; use outro e-mail"},
    "cli.user_created": {
        "en": "user {email} ({role}) created in {clinic!r} (id {id})",
        "es": "usuario {email} ({role}) creado en {clinic!r} (id {id})",
        "pt": "utilizador {email} ({role}) criado em {clinic!r} (id {id})"},
    "cli.user_unknown": {
        "en": "no user with the email {email!r}; check it (emails are the login names)",
        "es": "no hay ningún usuario con el correo {email!r}; compruébelo (los correos son los nombres de acceso)",
        "pt": "não há nenhum utilizador com o e-mail {email!r}; verifique-o (os e-mails são os nomes de acesso)"},
    "cli.user_unknown_in": {
        "en": "no user with the email {email!r} in {clinic!r}; check it (emails are the login names)",
        "es": "no hay ningún usuario con el correo {email!r} en {clinic!r}; compruébelo (los correos son los nombres "
              "de acceso)",
        "pt": "não há nenhum utilizador com o e-mail {email!r} em {clinic!r}; verifique-o (os e-mails são os nomes "
              "de acesso)"},
    "cli.user_ambiguous": {
        "en": "the email {email!r} has accounts in several clinics ({clinics}); say which with --clinic",
        "es": "el correo {email!r} tiene cuentas en varias clínicas ({clinics}); indique cuál con --clinic",
        "pt": "o e-mail {email!r} tem contas em várias clínicas ({clinics}); indique qual com --clinic"},
    "cli.user_deactivated": {
        "en": "user {email} deactivated: logins refused, {closed} browser session(s) closed",
        "es": "usuario {email} desactivado: inicios de sesión rechazados, {closed} sesión(es) de navegador cerrada(s)",
        "pt": "utilizador {email} desativado: inícios de sessão recusados, {closed} sessão(ões) de navegador "
              "fechada(s)"},
    "cli.password_changed": {
        "en": "password of {email} changed; {closed} browser session(s) closed",
        "es": "contraseña de {email} cambiada; {closed} sesión(es) de navegador cerrada(s)",
        "pt": "palavra-passe de {email} alterada; {closed} sessão(ões) de navegador fechada(s)"},
    "cli.password_prompt": {
        "en": "Password (at least {min} characters): ",
        "es": "Contraseña (al menos {min} caracteres): ",
        "pt": "Palavra-passe (pelo menos {min} caracteres): "},
    "cli.password_repeat": {
        "en": "Repeat the password: ", "es": "Repita la contraseña: ", "pt": "Repita a palavra-passe: "},
    "cli.passwords_differ": {
        "en": "the two passwords differ; run the command again",
        "es": "las dos contraseñas no coinciden; ejecute la orden de nuevo",
        "pt": "as duas palavras-passe não coincidem; execute o comando de novo"},
    # ``chakamo reprocess`` (app/cli/ops.py), in --lang: the statuses of its table (separated by "|"), a job, the end
    "cli.reprocess_statuses": {"en": "queued|current|busy|not ready", "es": "en cola|al día|ocupada|no lista",
                               "pt": "em fila|em dia|ocupada|não pronta"},
    "cli.reprocess_job": {"en": "job {id}", "es": "trabajo {id}", "pt": "tarefa {id}"},
    "cli.reprocess_counts": {
        "en": "{n} sessions: {counts}. {summary}.",
        "es": "{n} sesiones: {counts}. {summary}.",
        "pt": "{n} sessões: {counts}. {summary}."},
    # ``chakamo``'s own words in --lang (app/cli/language.py): argparse's, whose English entries are argparse's msgids
    # (%-placeholders: argparse fills them), the help frame, and the start-up lines of serve, migrate and worker
    "cli.description": {"en": "Clinical 3D knee kinematics from two IMUs.",
                        "es": "Cinemática clínica 3D de la rodilla con dos sensores inerciales.",
                        "pt": "Cinemática clínica 3D do joelho com dois sensores inerciais."},
    "cli.version_help": {"en": "show program's version number and exit", "es": "muestra la versión del programa y termina",
                         "pt": "mostra a versão do programa e termina"},
    # the one-line help of each command on `chakamo --help` and of the --lang option (app/cli/language.py's HELP)
    "cli.help_demo": {
        "en": "simulate a session with known truth, process it, print the accuracy",
        "es": "simular una sesión con verdad conocida, procesarla e imprimir la exactitud",
        "pt": "simular uma sessão com verdade conhecida, processá-la e mostrar a exatidão"},
    "cli.help_process": {
        "en": "process one recorded session folder into results.json",
        "es": "procesar la carpeta de una sesión grabada en results.json",
        "pt": "processar a pasta de uma sessão gravada em results.json"},
    "cli.help_view": {
        "en": "serve the live 3D femur-tibia animation of a processed session",
        "es": "servir la animación 3D en vivo de fémur y tibia de una sesión procesada",
        "pt": "servir a animação 3D ao vivo do fémur e da tíbia de uma sessão processada"},
    "cli.help_walk": {
        "en": "foot-mounted pedestrian dead reckoning of one walk",
        "es": "navegación a estima de una marcha con un sensor en el pie",
        "pt": "navegação por estima de uma marcha com um sensor no pé"},
    "cli.help_markov": {
        "en": "Markovian Kalman filters on a multi-segment research CSV",
        "es": "filtros de Kalman markovianos sobre un CSV de investigación de varios segmentos",
        "pt": "filtros de Kalman markovianos sobre um CSV de investigação de vários segmentos"},
    "cli.help_serve": {
        "en": "run the web application (embedded default: SQLite, local files)",
        "es": "ejecutar la aplicación web (integrada por defecto: SQLite, archivos locales)",
        "pt": "executar a aplicação web (integrada por omissão: SQLite, ficheiros locais)"},
    "cli.help_clinics": {
        "en": "manage clinics (tenants)",
        "es": "gestionar clínicas (inquilinos)",
        "pt": "gerir clínicas (inquilinos)"},
    "cli.help_users": {
        "en": "manage user accounts",
        "es": "gestionar cuentas de usuario",
        "pt": "gerir contas de utilizador"},
    "cli.help_tokens": {
        "en": "manage API tokens",
        "es": "gestionar tokens de API",
        "pt": "gerir tokens de API"},
    "cli.help_patients": {
        "en": "correct or erase a patient (operator)",
        "es": "corregir o borrar un paciente (operador)",
        "pt": "corrigir ou apagar um paciente (operador)"},
    "cli.help_sessions": {
        "en": "correct or erase a session (operator)",
        "es": "corregir o borrar una sesión (operador)",
        "pt": "corrigir ou apagar uma sessão (operador)"},
    "cli.help_retention": {
        "en": "list (dry run) or erase the sessions past the retention period",
        "es": "listar (simulacro) o borrar las sesiones que superan el plazo de conservación",
        "pt": "listar (simulação) ou apagar as sessões que ultrapassam o prazo de conservação"},
    "cli.help_migrate": {
        "en": "upgrade the database schema to this release and exit",
        "es": "actualizar el esquema de la base de datos a esta versión y terminar",
        "pt": "atualizar o esquema da base de dados para esta versão e terminar"},
    "cli.help_worker": {
        "en": "run a Celery worker for the processing jobs (CHAKAMO_JOB_BACKEND=celery)",
        "es": "ejecutar un trabajador Celery para los trabajos de procesamiento (CHAKAMO_JOB_BACKEND=celery)",
        "pt": "executar um trabalhador Celery para as tarefas de processamento (CHAKAMO_JOB_BACKEND=celery)"},
    "cli.help_reprocess": {
        "en": "queue every session since a date for processing with a filter",
        "es": "poner en cola todas las sesiones desde una fecha para procesarlas con un filtro",
        "pt": "pôr em fila todas as sessões desde uma data para as processar com um filtro"},
    "cli.help_lang_messages": {
        "en": "language of the messages (default: English)",
        "es": "idioma de los mensajes (por defecto: inglés)",
        "pt": "idioma das mensagens (por omissão: inglês)"},
    "cli.argparse_usage": {"en": "usage: ", "es": "uso: ", "pt": "utilização: "},
    "cli.argparse_positionals": {"en": "positional arguments", "es": "argumentos posicionales",
                                 "pt": "argumentos posicionais"},
    "cli.argparse_options": {"en": "options", "es": "opciones", "pt": "opções"},
    "cli.argparse_help": {"en": "show this help message and exit", "es": "muestra esta ayuda y termina",
                          "pt": "mostra esta ajuda e termina"},
    "cli.argparse_error": {"en": "%(prog)s: error: %(message)s\n", "es": "%(prog)s: error: %(message)s\n",
                           "pt": "%(prog)s: erro: %(message)s\n"},
    "cli.argparse_argument": {"en": "argument %(argument_name)s: %(message)s",
                              "es": "argumento %(argument_name)s: %(message)s",
                              "pt": "argumento %(argument_name)s: %(message)s"},
    "cli.argparse_unrecognized": {"en": "unrecognized arguments: %s", "es": "argumentos no reconocidos: %s",
                                  "pt": "argumentos não reconhecidos: %s"},
    "cli.argparse_required": {"en": "the following arguments are required: %s",
                              "es": "faltan estos argumentos obligatorios: %s",
                              "pt": "faltam estes argumentos obrigatórios: %s"},
    "cli.argparse_one_of": {"en": "one of the arguments %s is required", "es": "se necesita uno de los argumentos %s",
                            "pt": "é necessário um dos argumentos %s"},
    "cli.argparse_not_allowed": {"en": "not allowed with argument %s", "es": "no se admite junto con el argumento %s",
                                 "pt": "não é admitido com o argumento %s"},
    "cli.argparse_ignored": {"en": "ignored explicit argument %r", "es": "argumento explícito ignorado: %r",
                             "pt": "argumento explícito ignorado: %r"},
    "cli.argparse_expected_one": {"en": "expected one argument", "es": "se esperaba un valor",
                                  "pt": "esperava-se um valor"},
    "cli.argparse_expected_at_most_one": {"en": "expected at most one argument", "es": "se esperaba un valor como máximo",
                                          "pt": "esperava-se um valor no máximo"},
    "cli.argparse_expected_at_least_one": {"en": "expected at least one argument", "es": "se esperaba al menos un valor",
                                           "pt": "esperava-se pelo menos um valor"},
    "cli.argparse_expected_n": {"en": "expected %s arguments", "es": "número de valores esperado: %s",
                                "pt": "número de valores esperado: %s"},
    "cli.argparse_ambiguous": {"en": "ambiguous option: %(option)s could match %(matches)s",
                               "es": "opción ambigua: %(option)s puede ser %(matches)s",
                               "pt": "opção ambígua: %(option)s pode ser %(matches)s"},
    "cli.argparse_invalid_value": {"en": "invalid %(type)s value: %(value)r",
                                   "es": "valor no válido (%(type)s): %(value)r",
                                   "pt": "valor inválido (%(type)s): %(value)r"},
    "cli.argparse_invalid_choice": {"en": "invalid choice: %(value)r (choose from %(choices)s)",
                                    "es": "opción no válida: %(value)r (elija entre %(choices)s)",
                                    "pt": "opção inválida: %(value)r (escolha entre %(choices)s)"},
    "cli.argparse_invalid_choice_command": {"en": "unknown parser %(parser_name)r (choices: %(choices)s)",
                                            "es": "orden desconocida %(parser_name)r (elija entre %(choices)s)",
                                            "pt": "comando desconhecido %(parser_name)r (escolha entre %(choices)s)"},
    "cli.not_a_date": {"en": "{value!r} is not a date; write it as YYYY-MM-DD (e.g. 2026-03-01)",
                       "es": "{value!r} no es una fecha; escríbala como AAAA-MM-DD (p. ej. 2026-03-01)",
                       "pt": "{value!r} não é uma data; escreva-a como AAAA-MM-DD (p. ex. 2026-03-01)"},
    "cli.serve_started": {
        "en": "ChakaMo on http://{host}:{port}/ (data in {data_dir}); Ctrl-C stops it",
        "es": "ChakaMo en http://{host}:{port}/ (datos en {data_dir}); Ctrl-C lo detiene",
        "pt": "ChakaMo em http://{host}:{port}/ (dados em {data_dir}); Ctrl-C para-o"},
    # the server's start-up words to its operator in `chakamo serve --lang` (app/web/main.py: no user yet), and the
    # refusals of the environment (app/settings.py's table: the settings sit below this module, so they keep it)
    "cli.first_admin": {
        "en": "ChakaMo has no user yet. Create a clinic and its first admin:\n"
              "  chakamo clinics create \"My clinic\"\n"
              "  chakamo users create --clinic \"My clinic\" --email you@example.org --role admin --name \"Your Name\"\n"
              "(the second command asks for the password; use the same CHAKAMO_DATA_DIR / DATABASE_URL as the server)",
        "es": "ChakaMo aún no tiene ningún usuario. Cree una clínica y su primer administrador:\n"
              "  chakamo clinics create \"Mi clínica\"\n"
              "  chakamo users create --clinic \"Mi clínica\" --email usted@example.org --role admin --name \"Su Nombre\"\n"
              "(la segunda orden pide la contraseña; use el mismo CHAKAMO_DATA_DIR / DATABASE_URL que el servidor)",
        "pt": "O ChakaMo ainda não tem nenhum utilizador. Crie uma clínica e o seu primeiro administrador:\n"
              "  chakamo clinics create \"A minha clínica\"\n"
              "  chakamo users create --clinic \"A minha clínica\" --email o.seu.nome@example.org --role admin "
              "--name \"O Seu Nome\"\n"
              "(o segundo comando pede a palavra-passe; use o mesmo CHAKAMO_DATA_DIR / DATABASE_URL que o servidor)"},
    **SETTINGS_MESSAGES,
    "cli.migrated": {"en": "database schema up to date ({url})", "es": "esquema de la base de datos al día ({url})",
                     "pt": "esquema da base de dados atualizado ({url})"},
    "cli.worker_started": {
        "en": "ChakaMo worker: {n} processes on the queue {queue}; SIGTERM lets the running jobs finish, then stops it",
        "es": "Trabajador de ChakaMo: {n} procesos en la cola {queue}; SIGTERM deja terminar los trabajos en curso y "
              "después lo detiene",
        "pt": "Trabalhador do ChakaMo: {n} processos na fila {queue}; SIGTERM deixa terminar as tarefas em curso e "
              "depois para-o"},
    "cli.worker_needs_celery": {
        "en": "chakamo worker runs the distributed jobs: set CHAKAMO_JOB_BACKEND=celery and "
              "CHAKAMO_BROKER_URL=redis://HOST:6379/0 (the embedded `chakamo serve` needs no worker)",
        "es": "chakamo worker ejecuta los trabajos distribuidos: defina CHAKAMO_JOB_BACKEND=celery y "
              "CHAKAMO_BROKER_URL=redis://HOST:6379/0 (el `chakamo serve` integrado no necesita ningún trabajador)",
        "pt": "chakamo worker executa as tarefas distribuídas: defina CHAKAMO_JOB_BACKEND=celery e "
              "CHAKAMO_BROKER_URL=redis://HOST:6379/0 (o `chakamo serve` integrado não precisa de nenhum trabalhador)"},
    "cli.concurrency_min": {"en": "--concurrency must be at least 1; give a number of processes such as 2",
                            "es": "--concurrency debe ser al menos 1; indique un número de procesos, p. ej. 2",
                            "pt": "--concurrency deve ser pelo menos 1; indique um número de processos, p. ex. 2"},
    "account.browser_only": {
        "en": "This needs a browser login (an API token has no password or sessions); log in with your email.",
        "es": "Esto requiere iniciar sesión en el navegador (un token de API no tiene contraseña ni sesiones); inicie "
              "sesión con su correo.",
        "pt": "Isto requer um início de sessão no navegador (um token de API não tem palavra-passe nem sessões); inicie "
              "sessão com o seu e-mail."},
    "account.no_user": {
        "en": "No user {id} in your clinic; check the id.",
        "es": "No hay ningún usuario {id} en su clínica; compruebe el identificador.",
        "pt": "Não há nenhum utilizador {id} na sua clínica; verifique o identificador."},
    "account.no_session": {
        "en": "No open session {id} of yours; reload the list.",
        "es": "No tiene ninguna sesión abierta {id}; vuelva a cargar la lista.",
        "pt": "Não tem nenhuma sessão aberta {id}; recarregue a lista."},
    "account.this_session": {
        "en": "This is the session you are using; log out to end it.",
        "es": "Es la sesión que está usando; cierre sesión para terminarla.",
        "pt": "É a sessão que está a usar; termine a sessão para a fechar."},
    "account.not_yourself": {
        "en": "You cannot change your own role or deactivate yourself; ask another admin of your clinic.",
        "es": "No puede cambiar su propio rol ni desactivarse; pídaselo a otro administrador de su clínica.",
        "pt": "Não pode alterar o seu próprio papel nem desativar-se; peça a outro administrador da sua clínica."},
    "account.email_unavailable": {
        "en": "The email {email} already has an account in your clinic; use another email, or change that "
              "account.",
        "es": "El correo {email} ya tiene una cuenta en su clínica; use otro correo o modifique esa cuenta.",
        "pt": "O e-mail {email} já tem uma conta na sua clínica; use outro e-mail ou altere essa conta."},
    # API tokens and logins presented but refused (app.web.api.deps)
    "auth.bearer_malformed": {
        "en": "The Authorization header must be 'Bearer <token>'; an administrator creates tokens on the "
              "Administration page (API tokens) or with `chakamo tokens create`.",
        "es": "La cabecera Authorization debe ser 'Bearer <token>'; un administrador crea tokens en la página de "
              "Administración (tokens de API) o con `chakamo tokens create`.",
        "pt": "O cabeçalho Authorization deve ser 'Bearer <token>'; um administrador cria tokens na página de "
              "Administração (tokens de API) ou com `chakamo tokens create`."},
    "auth.token_unknown": {
        "en": "Unknown or revoked API token; check it, or ask an administrator for a new one (Administration page, "
              "API tokens; or `chakamo tokens create`).",
        "es": "Token de API desconocido o revocado; compruébelo o pida uno nuevo a un administrador (página de "
              "Administración, tokens de API; o `chakamo tokens create`).",
        "pt": "Token de API desconhecido ou revogado; verifique-o ou peça um novo a um administrador (página de "
              "Administração, tokens de API; ou `chakamo tokens create`)."},
    "auth.token_expired": {
        "en": "This API token has expired; use its successor or a new one (an administrator rotates or creates "
              "tokens on the Administration page, API tokens; or `chakamo tokens rotate` / `create`).",
        "es": "Este token de API ha caducado; use su sucesor o uno nuevo (un administrador renueva o crea tokens en "
              "la página de Administración, tokens de API; o `chakamo tokens rotate` / `create`).",
        "pt": "Este token de API expirou; use o seu sucessor ou um novo (um administrador renova ou cria tokens na "
              "página de Administração, tokens de API; ou `chakamo tokens rotate` / `create`)."},
    "auth.not_logged_in": {
        "en": "Not logged in; log in, or send 'Authorization: Bearer <token>'.",
        "es": "No ha iniciado sesión; inicie sesión o envíe 'Authorization: Bearer <token>'.",
        "pt": "Não iniciou sessão; inicie sessão ou envie 'Authorization: Bearer <token>'."},
    "auth.login_closed": {
        "en": "Your session has expired or was closed; log in again.",
        "es": "Su sesión ha caducado o se cerró; inicie sesión de nuevo.",
        "pt": "A sua sessão expirou ou foi encerrada; inicie sessão de novo."},
    "auth.csrf": {
        "en": "Missing or wrong {header} header; send the csrf_token that login and /auth/me return.",
        "es": "Falta la cabecera {header} o es incorrecta; envíe el csrf_token que devuelven el inicio de sesión "
              "y /auth/me.",
        "pt": "Falta o cabeçalho {header} ou está errado; envie o csrf_token que o início de sessão e /auth/me "
              "devolvem."},
    "auth.role_needed": {
        "en": "This needs the {role} role (yours is {yours}); ask a clinic admin.",
        "es": "Esto necesita el rol {role} (el suyo es {yours}); pídalo a un administrador de la clínica.",
        "pt": "Isto precisa do papel {role} (o seu é {yours}); peça a um administrador da clínica."},
    "auth.scope_missing": {
        "en": "This API token lacks the scope {scope} (it has {scopes}); an administrator creates a token with it "
              "on the Administration page (API tokens) or with `chakamo tokens create --scope ...`.",
        "es": "A este token de API le falta el ámbito {scope} (tiene {scopes}); un administrador crea un token con "
              "él en la página de Administración (tokens de API) o con `chakamo tokens create --scope ...`.",
        "pt": "A este token de API falta o âmbito {scope} (tem {scopes}); um administrador cria um token com ele "
              "na página de Administração (tokens de API) ou com `chakamo tokens create --scope ...`."},
    "auth.grant_beyond_scopes": {
        "en": "An API token may only hand out the scopes it holds ({scopes}): a token with more, or a user account, "
              "is created by an administrator logged in to the web app (Administration page) or on the server "
              "(`chakamo tokens create`, `chakamo users create`).",
        "es": "Un token de API solo puede conceder los ámbitos que tiene ({scopes}): un token con más, o una cuenta "
              "de usuario, lo crea un administrador con sesión iniciada en la aplicación web (página de "
              "Administración) o en el servidor (`chakamo tokens create`, `chakamo users create`).",
        "pt": "Um token de API só pode conceder os âmbitos que tem ({scopes}): um token com mais, ou uma conta de "
              "utilizador, é criado por um administrador com sessão iniciada na aplicação web (página de "
              "Administração) ou no servidor (`chakamo tokens create`, `chakamo users create`)."},
    "auth.grant_beyond_expiry": {
        "en": "An API token may only hand out access that ends when it does ({until} UTC) or sooner: a longer-lived "
              "token, or a user account, is created by an administrator logged in to the web app (Administration "
              "page) or on the server (`chakamo tokens create`, `chakamo users create`).",
        "es": "Un token de API solo puede conceder un acceso que termine cuando él ({until} UTC) o antes: un token "
              "más duradero, o una cuenta de usuario, lo crea un administrador con sesión iniciada en la aplicación "
              "web (página de Administración) o en el servidor (`chakamo tokens create`, `chakamo users create`).",
        "pt": "Um token de API só pode conceder um acesso que termine quando ele ({until} UTC) ou antes: um token "
              "mais duradouro, ou uma conta de utilizador, é criado por um administrador com sessão iniciada na "
              "aplicação web (página de Administração) ou no servidor (`chakamo tokens create`, "
              "`chakamo users create`)."},
    # webhooks (app.web.api.webhooks)
    "webhook.url_invalid": {
        "en": "The webhook URL {url} is not an absolute https:// address; give the receiver's full https address.",
        "es": "La URL del webhook {url} no es una dirección https:// absoluta; indique la dirección https completa "
              "del receptor.",
        "pt": "A URL do webhook {url} não é um endereço https:// absoluto; indique o endereço https completo do "
              "receptor."},
    "webhook.url_refused": {
        "en": "This server does not send webhooks to {host}; ask your ChakaMo administrator to add it to "
              "CHAKAMO_WEBHOOK_ALLOWED_HOSTS.",
        "es": "Este servidor no envía webhooks a {host}; pida a su administrador de ChakaMo que lo añada a "
              "CHAKAMO_WEBHOOK_ALLOWED_HOSTS.",
        "pt": "Este servidor não envia webhooks para {host}; peça ao seu administrador do ChakaMo que o adicione a "
              "CHAKAMO_WEBHOOK_ALLOWED_HOSTS."},
    # a delivery's last failed attempt (app.web.webhooks.trail_error: webhooks and the FHIR push)
    "webhook.no_connection": {
        "en": "No answer from the receiver (it could not be reached, or did not answer within {seconds} s); it is "
              "retried later: check that the receiver is up and answers quickly.",
        "es": "Sin respuesta del receptor (no se pudo contactar o no respondió en {seconds} s); se reintentará más "
              "tarde: compruebe que el receptor está en marcha y responde rápido.",
        "pt": "Sem resposta do recetor (não foi possível contactá-lo ou não respondeu em {seconds} s); será tentado "
              "de novo mais tarde: verifique que o recetor está ativo e responde depressa."},
    "webhook.http_status": {
        "en": "The receiver answered HTTP {status}; it is retried later: check the receiver's log for why.",
        "es": "El receptor respondió HTTP {status}; se reintentará más tarde: consulte el registro del receptor "
              "para saber por qué.",
        "pt": "O recetor respondeu HTTP {status}; será tentado de novo mais tarde: consulte o registo do recetor "
              "para saber porquê."},
    "webhook.secret_unreadable": {
        "en": "The webhook's secret cannot be read (the server's key was changed); delete this webhook and "
              "subscribe again.",
        "es": "No se puede leer el secreto del webhook (se cambió la clave del servidor); elimine este webhook y "
              "suscríbase de nuevo.",
        "pt": "Não é possível ler o segredo do webhook (a chave do servidor foi alterada); elimine este webhook e "
              "subscreva de novo."},
    "fhir.not_exportable": {
        "en": "This analysis was not pushed to the FHIR server: it was superseded, or its stored data cannot be "
              "expressed in FHIR (GET /fhir/DiagnosticReport/<session id> says why); correct the record and process "
              "the session again.",
        "es": "Este análisis no se envió al servidor FHIR: fue reemplazado o sus datos guardados no se pueden "
              "expresar en FHIR (GET /fhir/DiagnosticReport/<id de la sesión> dice por qué); corrija el registro y "
              "procese la sesión de nuevo.",
        "pt": "Esta análise não foi enviada ao servidor FHIR: foi substituída ou os seus dados guardados não podem "
              "ser expressos em FHIR (GET /fhir/DiagnosticReport/<id da sessão> diz porquê); corrija o registo e "
              "processe a sessão de novo."},
    # a pattern (``*``, ``*.example.org``) or no host at all where the webhook's host goes (app.web.api.webhooks)
    "webhook.host_invalid": {
        "en": "The webhook URL {url} does not name one host (a host name or an IP address; {host} is not one); give "
              "the receiver's own address.",
        "es": "La URL del webhook {url} no nombra un host (un nombre de host o una dirección IP; {host} no lo es); "
              "indique la dirección propia del receptor.",
        "pt": "A URL do webhook {url} não nomeia um host (um nome de host ou um endereço IP; {host} não o é); "
              "indique o endereço próprio do recetor."},
    # the last attempt failed and no other follows (state failed; app.web.webhooks.trail_error)
    "webhook.no_connection.final": {
        "en": "No answer from the receiver (it could not be reached, or did not answer within {seconds} s) at the "
              "last attempt; it is not retried: check that the receiver is up and answers quickly.",
        "es": "Sin respuesta del receptor (no se pudo contactar o no respondió en {seconds} s) en el último "
              "intento; no se reintentará: compruebe que el receptor está en marcha y responde rápido.",
        "pt": "Sem resposta do recetor (não foi possível contactá-lo ou não respondeu em {seconds} s) na última "
              "tentativa; não será tentado de novo: verifique que o recetor está ativo e responde depressa."},
    "webhook.http_status.final": {
        "en": "The receiver answered HTTP {status} at the last attempt; it is not retried: check the receiver's log "
              "for why.",
        "es": "El receptor respondió HTTP {status} en el último intento; no se reintentará: consulte el registro "
              "del receptor para saber por qué.",
        "pt": "O recetor respondeu HTTP {status} na última tentativa; não será tentado de novo: consulte o registo "
              "do recetor para saber porquê."},
    # a report the FHIR export cannot name its patient in (app.web.fhir.FhirExportError.code; the push's trail)
    "fhir.patient_unreferenced": {
        "en": "The report cannot name its patient on the FHIR server: the patient has no FHIR reference (Patient/<id>) "
              "and no record number the server can find; give the patient its FHIR reference, or ask your ChakaMo "
              "administrator to set CHAKAMO_PATIENT_IDENTIFIER_SYSTEM, then process the session again.",
        "es": "El informe no puede nombrar a su paciente en el servidor FHIR: el paciente no tiene referencia FHIR "
              "(Patient/<id>) ni un número de historia que el servidor pueda encontrar; dé al paciente su referencia "
              "FHIR o pida a su administrador de ChakaMo que configure CHAKAMO_PATIENT_IDENTIFIER_SYSTEM, y procese la "
              "sesión de nuevo.",
        "pt": "O relatório não pode nomear o seu paciente no servidor FHIR: o paciente não tem referência FHIR "
              "(Patient/<id>) nem um número de processo que o servidor possa encontrar; dê ao paciente a sua "
              "referência FHIR ou peça ao seu administrador do ChakaMo que configure "
              "CHAKAMO_PATIENT_IDENTIFIER_SYSTEM, e processe a sessão de novo."},
    "fhir.patient_reference_invalid": {
        "en": "The patient's FHIR reference is not a FHIR reference such as Patient/123; correct it in the patient's "
              "record, then process the session again.",
        "es": "La referencia FHIR del paciente no es una referencia FHIR como Patient/123; corríjala en la ficha del "
              "paciente y procese la sesión de nuevo.",
        "pt": "A referência FHIR do paciente não é uma referência FHIR como Patient/123; corrija-a no registo do "
              "paciente e processe a sessão de novo."},
}


def language(request: "Request | None") -> str:
    """The first of es/en/pt that the request's ``Accept-Language`` asks for (by its q values), else English."""
    header = request.headers.get("accept-language", "") if request is not None else ""
    ranked: list[tuple[float, int, str]] = []
    for i, item in enumerate(header.split(",")):
        tag, _, params = item.strip().partition(";")
        q = 1.0
        if params.strip().startswith("q="):
            try:
                q = float(params.strip()[2:])
            except ValueError:
                q = 0.0
        primary = tag.strip().lower().split("-")[0]
        if primary in LANGUAGES and q > 0:
            ranked.append((-q, i, primary))
    return min(ranked)[2] if ranked else DEFAULT


def render(code: str, lang: str = DEFAULT, **params) -> str:
    """The sentence of ``code`` in ``lang`` (English for a language not in the catalogue)."""
    texts = CATALOGUE[code]
    return texts.get(lang, texts[DEFAULT]).format(**params)


def refusal(request: "Request | None", status: int, code: str, headers: dict[str, str] | None = None,
            **params) -> HTTPException:
    """The :class:`app.web.refusals.Refusal` answering ``code`` with its ``detail`` in the request's language (the
    same body and :data:`CODE_HEADER` as every refusal)."""
    from app.web.refusals import Refusal  # that module reads this one's table

    return Refusal(status, code, headers=headers, lang=language(request), **params)


def placeholders(template: str) -> set[str]:
    """The ``{name}`` fields of a template (the tests check each language has the same)."""
    return {f for _, f, _, _ in string.Formatter().parse(template) if f}


__all__ = ["CATALOGUE", "CODE_HEADER", "LANGUAGES", "language", "placeholders", "refusal", "render"]
