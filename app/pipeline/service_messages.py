"""The server's own refusals and answers a user can cause, in Spanish, English and Portuguese (one table).

The ingestion's messages name a file (:mod:`app.pipeline.ingestion.messages`); these are about a request or a
session as a whole: ``request.*`` the web API's refusals of a request (:mod:`app.web.limits`,
:mod:`app.web.api.recordings`), ``session.*`` what the upload checks answer (:mod:`app.store.checks`).
Same templates and rules as the ingestion's catalogue (``{name}`` placeholders, a sentence that ends saying
what to do); :func:`render` and :func:`message_dict` are that module's, on this table.
"""

from __future__ import annotations

from typing import Any, Mapping

from app.pipeline.ingestion.messages import CATALOGUE as INGESTION_CATALOGUE
from app.pipeline.ingestion.messages import LANGUAGES
from app.pipeline.ingestion.messages import message_dict as _message_dict
from app.pipeline.ingestion.messages import render as _render

CATALOGUE: dict[str, dict[str, str]] = {
    "session.check_too_slow": {
        "en": "The files could not be checked within {seconds} s and the check was stopped; check that each "
              "file is a recording of this session (a file made to be slow to read is refused), delete the "
              "wrong one and upload it again.",
        "es": "Los archivos no se pudieron comprobar en {seconds} s y la comprobación se detuvo; compruebe que "
              "cada archivo es una grabación de esta sesión (se rechaza un archivo hecho para ser lento de leer), "
              "borre el equivocado y súbalo de nuevo.",
        "pt": "Os arquivos não puderam ser verificados em {seconds} s e a verificação foi interrompida; verifique "
              "se cada arquivo é uma gravação desta sessão (um arquivo feito para ser lento de ler é recusado), "
              "apague o errado e envie-o de novo."},
    "session.check_stopped": {
        "en": "The files could not be checked: the check stopped unexpectedly; delete the file you added last and "
              "upload it again, and if it happens again tell your ChakaMo administrator.",
        "es": "Los archivos no se pudieron comprobar: la comprobación se detuvo inesperadamente; borre el último "
              "archivo que añadió y súbalo de nuevo, y si vuelve a ocurrir avise a su administrador de ChakaMo.",
        "pt": "Os arquivos não puderam ser verificados: a verificação parou inesperadamente; apague o último "
              "arquivo que adicionou e envie-o de novo, e se voltar a acontecer avise o seu administrador do "
              "ChakaMo."},
    "session.check_busy": {
        "en": "The files are stored, but the server could not check them within {seconds} s because it is busy "
              "checking other files; open the session again in a moment and they are checked then.",
        "es": "Los archivos están guardados, pero el servidor no pudo comprobarlos en {seconds} s porque está "
              "ocupado comprobando otros archivos; abra la sesión de nuevo en un momento y se comprobarán entonces.",
        "pt": "Os arquivos estão guardados, mas o servidor não pôde verificá-los em {seconds} s porque está "
              "ocupado verificando outros arquivos; abra a sessão de novo daqui a pouco e serão verificados então."},
    "session.no_files_yet": {
        "en": "No recordings yet; upload the session's files.",
        "es": "Todavía no hay grabaciones; suba los archivos de la sesión.",
        "pt": "Ainda não há gravações; envie os arquivos da sessão."},
    "session.being_checked": {
        "en": "The session's files are being checked; reload in a moment.",
        "es": "Se están comprobando los archivos de la sesión; recargue en un momento.",
        "pt": "Os arquivos da sessão estão sendo verificados; recarregue daqui a pouco."},
    "session.check_deferred": {
        "en": "The files are stored, but the server could not check them now; the check runs again when the "
              "session is opened or processed.",
        "es": "Los archivos están guardados, pero el servidor no pudo comprobarlos ahora; la comprobación se repite "
              "cuando se abra o se procese la sesión.",
        "pt": "Os arquivos estão guardados, mas o servidor não pôde verificá-los agora; a verificação se repete "
              "quando a sessão for aberta ou processada."},
    "session.knee.left": {"en": "Left knee:", "es": "Rodilla izquierda:", "pt": "Joelho esquerdo:"},
    "session.knee.right": {"en": "Right knee:", "es": "Rodilla derecha:", "pt": "Joelho direito:"},
    "session.recognised": {
        "en": "{segment} {role}: {files} — segment from {segment_how}{segment_evidence}, role from "
              "{role_how}{role_evidence}",
        "es": "{segment} {role}: {files} — segmento según {segment_how}{segment_evidence}, función según "
              "{role_how}{role_evidence}",
        "pt": "{segment} {role}: {files} — segmento segundo {segment_how}{segment_evidence}, função segundo "
              "{role_how}{role_evidence}"},
    "request.host_not_allowed": {
        "en": "This server does not answer to the address {host}; use the address your ChakaMo administrator "
              "gave you (CHAKAMO_ALLOWED_HOSTS).",
        "es": "Este servidor no responde a la dirección {host}; use la dirección que le dio su administrador de "
              "ChakaMo (CHAKAMO_ALLOWED_HOSTS).",
        "pt": "Este servidor não responde ao endereço {host}; use o endereço que o seu administrador do ChakaMo "
              "lhe deu (CHAKAMO_ALLOWED_HOSTS)."},
    "request.public_url_missing": {
        "en": "The FHIR export needs the namespace of this server's identifiers, which is not set; ask your ChakaMo "
              "administrator to set CHAKAMO_PUBLIC_URL (or CHAKAMO_FHIR_IDENTIFIER_BASE).",
        "es": "La exportación FHIR necesita el espacio de nombres de los identificadores de este servidor, que no "
              "está configurado; pida a su administrador de ChakaMo que configure CHAKAMO_PUBLIC_URL (o "
              "CHAKAMO_FHIR_IDENTIFIER_BASE).",
        "pt": "A exportação FHIR precisa do espaço de nomes dos identificadores deste servidor, que não está "
              "configurado; peça ao administrador do ChakaMo que configure CHAKAMO_PUBLIC_URL (ou "
              "CHAKAMO_FHIR_IDENTIFIER_BASE)."},
    "request.body_too_large": {
        "en": "The request body is larger than {limit_kb} kB; requests other than uploads of recordings take "
              "small JSON bodies — send less.",
        "es": "El cuerpo de la petición ocupa más de {limit_kb} kB; las peticiones que no son subidas de "
              "grabaciones llevan cuerpos JSON pequeños: envíe menos.",
        "pt": "O corpo da requisição ocupa mais de {limit_kb} kB; as requisições que não são envios de gravações "
              "levam corpos JSON pequenos: envie menos."},
    "request.multipart_malformed": {
        "en": "The multipart body is malformed; send the files with a standard form upload.",
        "es": "El cuerpo multipart está mal formado; envíe los archivos con un formulario estándar.",
        "pt": "O corpo multipart está malformado; envie os arquivos com um formulário padrão."},
    "request.boundary_too_long": {
        "en": "The multipart boundary has {length} characters; a boundary has 1 to 70 (RFC 2046) — send the "
              "files with a standard form upload.",
        "es": "El delimitador multipart tiene {length} caracteres; un delimitador tiene de 1 a 70 (RFC 2046): "
              "envíe los archivos con un formulario estándar.",
        "pt": "O delimitador multipart tem {length} caracteres; um delimitador tem de 1 a 70 (RFC 2046): envie "
              "os arquivos com um formulário padrão."},
    "request.file_name_controls": {
        "en": "File name {name} holds invisible characters that reorder how it is shown (Unicode bidirectional "
              "controls); rename the file (letters, digits, - _ .).",
        "es": "El nombre de archivo {name} contiene caracteres invisibles que cambian el orden en que se muestra "
              "(controles bidireccionales de Unicode); cambie el nombre del archivo (letras, dígitos, - _ .).",
        "pt": "O nome de arquivo {name} contém caracteres invisíveis que mudam a ordem em que é mostrado "
              "(controles bidirecionais do Unicode); renomeie o arquivo (letras, dígitos, - _ .)."},
    "request.disk_full": {
        "en": "The server's disk is full, so the files could not be stored and none was recorded. Ask your "
              "ChakaMo administrator to free space, then upload them again.",
        "es": "El disco del servidor está lleno, así que los archivos no se pudieron guardar y no se registró "
              "ninguno. Pida a su administrador de ChakaMo que libere espacio y súbalos de nuevo.",
        "pt": "O disco do servidor está cheio, por isso os arquivos não puderam ser guardados e nenhum foi "
              "registrado. Peça ao seu administrador do ChakaMo que libere espaço e envie-os de novo."},
    # ------------------------------------------------------------------------ uploads (app/web/api/recordings.py)
    "request.file_name_unusable": {
        "en": "File name {name} is not usable; rename the file (letters, digits, - _ .).",
        "es": "El nombre de archivo {name} no se puede usar; cambie el nombre del archivo (letras, dígitos, - _ .).",
        "pt": "O nome de arquivo {name} não pode ser usado; renomeie o arquivo (letras, dígitos, - _ .)."},
    "request.too_many_parts": {
        "en": "Too many parts in one upload; send at most {max_files} files and the fields segment and role.",
        "es": "Demasiadas partes en una subida; envíe como mucho {max_files} archivos y los campos segment y role.",
        "pt": "Partes demais num envio; envie no máximo {max_files} arquivos e os campos segment e role."},
    "request.part_header_too_long": {
        "en": "A multipart header is too long; send the files with a standard form upload.",
        "es": "Un encabezado multipart es demasiado largo; envíe los archivos con un formulario estándar.",
        "pt": "Um cabeçalho multipart é longo demais; envie os arquivos com um formulário padrão."},
    "request.too_many_part_headers": {
        "en": "Too many headers in one multipart part; send a standard form upload.",
        "es": "Demasiados encabezados en una parte multipart; envíe un formulario estándar.",
        "pt": "Cabeçalhos demais numa parte multipart; envie um formulário padrão."},
    "request.field_not_accepted": {
        "en": "Form field {field} is not accepted; send the files in the field 'files' and, optionally, the "
              "fields 'segment' and 'role'.",
        "es": "El campo de formulario {field} no se acepta; envíe los archivos en el campo 'files' y, si quiere, "
              "los campos 'segment' y 'role'.",
        "pt": "O campo de formulário {field} não é aceito; envie os arquivos no campo 'files' e, se quiser, os "
              "campos 'segment' e 'role'."},
    "request.field_twice": {
        "en": "Form field {field} sent twice; send it once per upload.",
        "es": "El campo de formulario {field} se envió dos veces; envíelo una vez por subida.",
        "pt": "O campo de formulário {field} foi enviado duas vezes; envie-o uma vez por envio."},
    "request.file_in_other_field": {
        "en": "File sent in form field {field}; send every file in the field 'files'.",
        "es": "Archivo enviado en el campo de formulario {field}; envíe cada archivo en el campo 'files'.",
        "pt": "Arquivo enviado no campo de formulário {field}; envie cada arquivo no campo 'files'."},
    "request.file_type": {
        "en": "{file}: files of type {suffix} are not accepted; upload {allowed} files (CSV of MetaBase, Xsens, "
              "Shimmer, phyphox or the generic layout, thesis Excel, zip of Sensor Logger or phyphox, session.json; "
              "an APDM .h5 file is read by the command line: chakamo process).",
        "es": "{file}: no se aceptan archivos del tipo {suffix}; suba archivos {allowed} (CSV de MetaBase, Xsens, "
              "Shimmer, phyphox o del formato genérico, Excel de la tesis, zip de Sensor Logger o phyphox, "
              "session.json; un archivo .h5 de APDM se lee con la línea de comandos: chakamo process).",
        "pt": "{file}: arquivos do tipo {suffix} não são aceitos; envie arquivos {allowed} (CSV do MetaBase, Xsens, "
              "Shimmer, phyphox ou do formato genérico, Excel da tese, zip do Sensor Logger ou phyphox, "
              "session.json; um arquivo .h5 da APDM é lido pela linha de comando: chakamo process)."},
    "request.json_not_manifest": {
        "en": "{file}: the only JSON file a session takes is its {manifest}; rename it.",
        "es": "{file}: el único archivo JSON que admite una sesión es su {manifest}; cámbiele el nombre.",
        "pt": "{file}: o único arquivo JSON que uma sessão aceita é o seu {manifest}; renomeie-o."},
    "request.too_many_files": {
        "en": "More than {max_files} files in one upload; send at most {max_files} at a time.",
        "es": "Más de {max_files} archivos en una subida; envíe como mucho {max_files} cada vez.",
        "pt": "Mais de {max_files} arquivos num envio; envie no máximo {max_files} de cada vez."},
    "request.file_too_large": {
        "en": "{file} is larger than the {limit_mb} MB limit; check that it is a recording of this session (or "
              "ask the administrator to raise CHAKAMO_MAX_FILE_MB).",
        "es": "{file} supera el límite de {limit_mb} MB; compruebe que es una grabación de esta sesión (o pida al "
              "administrador que aumente CHAKAMO_MAX_FILE_MB).",
        "pt": "{file} excede o limite de {limit_mb} MB; verifique se é uma gravação desta sessão (ou peça ao "
              "administrador que aumente CHAKAMO_MAX_FILE_MB)."},
    "request.field_too_long": {
        "en": "Form field {field} is too long; it takes a short word.",
        "es": "El campo de formulario {field} es demasiado largo; admite una palabra corta.",
        "pt": "O campo de formulário {field} é longo demais; aceita uma palavra curta."},
    "request.upload_too_large": {
        "en": "The upload is larger than {max_files} files of {limit_mb} MB; send fewer or smaller files.",
        "es": "La subida ocupa más que {max_files} archivos de {limit_mb} MB; envíe menos archivos o más pequeños.",
        "pt": "O envio é maior que {max_files} arquivos de {limit_mb} MB; envie menos arquivos ou menores."},
    "request.uploads_busy": {
        "en": "Too many uploads are in progress on this server; try again in a minute.",
        "es": "Hay demasiadas subidas en curso en este servidor; inténtelo de nuevo en un minuto.",
        "pt": "Há envios demais em andamento neste servidor; tente de novo em um minuto."},
    "request.not_multipart": {
        "en": "Send the files as multipart/form-data in the field 'files'.",
        "es": "Envíe los archivos como multipart/form-data en el campo 'files'.",
        "pt": "Envie os arquivos como multipart/form-data no campo 'files'."},
    "request.no_file": {
        "en": "No file in the request; send the recordings in the multipart field 'files'.",
        "es": "No hay ningún archivo en la petición; envíe las grabaciones en el campo multipart 'files'.",
        "pt": "Não há nenhum arquivo na requisição; envie as gravações no campo multipart 'files'."},
    "request.cursor_invalid": {
        "en": "The cursor is not one this server gave; send the X-Next-Cursor of the previous page, or no cursor "
              "for the first page.",
        "es": "El cursor no es uno que haya dado este servidor; envíe el X-Next-Cursor de la página anterior, o "
              "ningún cursor para la primera página.",
        "pt": "O cursor não é um que este servidor tenha dado; envie o X-Next-Cursor da página anterior, ou nenhum "
              "cursor para a primeira página."},
    "request.idempotency_key_invalid": {
        "en": "The Idempotency-Key must be 1 to {limit} printable ASCII characters (a UUID, for example).",
        "es": "La Idempotency-Key debe tener de 1 a {limit} caracteres ASCII imprimibles (un UUID, por ejemplo).",
        "pt": "A Idempotency-Key deve ter de 1 a {limit} caracteres ASCII imprimíveis (um UUID, por exemplo)."},
}


def render(code: str, params: Mapping[str, Any], lang: str = "en") -> str:
    """Message ``code`` of :data:`CATALOGUE` in ``lang`` (es/en/pt), filled from ``params``."""
    return _render(code, params, lang, CATALOGUE)


def message_dict(code: str, params: Mapping[str, Any]) -> dict[str, Any]:
    """``{"code", "params", "message": {lang: text}}`` of :data:`CATALOGUE` for JSON answers."""
    return _message_dict(code, params, CATALOGUE)


def item(code: str | None, params: Mapping[str, Any], text: str, *, note: bool = False) -> dict[str, Any]:
    """A message as stored (the session's ingestion check, :mod:`app.store.checks`): its ``code`` and ``params``,
    and ``text`` (English, what older readers show).  ``note=True``: an ingestion :class:`~app.pipeline.ingestion.Note`
    (its ``params`` carry ``variant``, ``segment``, ``role``), rendered as the note renders itself."""
    out: dict[str, Any] = {"code": code, "params": dict(params), "text": text}
    if note:
        out["note"] = True
    return out


def render_item(stored: Mapping[str, Any] | str, lang: str = "en") -> str:
    """A stored :func:`item` in ``lang``: this table, the pipeline's and the ingestion's codes
    (:func:`app.pipeline.messages.render_message`); a note through its own catalogue code or, for the notes only the
    reports translate, ``warning.ingestion_note.<variant>`` (:func:`reports.warning_text.warning_text`).  A plain
    string (stored before codes were) and anything without a translation stay as written."""
    if isinstance(stored, str):
        return stored
    code, params, text = stored.get("code"), stored.get("params") or {}, str(stored.get("text") or "")
    if stored.get("note"):
        from app.pipeline.ingestion.model import Note
        from reports.warning_text import warning_text

        note = Note(text, params)
        if note.code is not None:
            return note.message(lang)
        return warning_text({"code": "ingestion_note", "message": text, "params": dict(params)}, lang)[0]
    if code in CATALOGUE:
        return render(code, params, lang)
    from app.pipeline.messages import known, render_message

    return render_message(code, params, lang) if code and known(code) else text


def _how(method: str) -> Any:
    slug = "how_" + "".join(c if c.isalnum() else "_" for c in method.lower()).strip("_").replace("__", "_")
    return {"code": f"word.{slug}"} if f"word.{slug}" in INGESTION_CATALOGUE else method


def recognised_item(segment: str, role: str, source: Mapping[str, Any]) -> dict[str, Any]:
    """The session check's line for the recording ``segment`` / ``role`` whose ``source`` is
    :attr:`app.pipeline.ingestion.AlignedRecording.source`: its files and how its segment and role were found."""
    from pathlib import Path

    files = [Path(f).name for f in source.get("files", ())]
    if len(files) > 1:
        what: Any = {"code": "word.recording_group",
                     "params": {"label": source.get("label"), "n": len(files), "format": source.get("format")}}
    else:
        what = ", ".join(files)
    params: dict[str, Any] = {"segment": {"code": f"word.{segment}"}, "role": {"code": f"word.{role}"}, "files": what}
    found = source.get("found_by") or {}
    for key in ("segment", "role"):
        method, evidence = found.get(key) or ("session.json", "")
        params[f"{key}_how"] = _how(method)
        params[f"{key}_evidence"] = f" ('{evidence}')" if evidence else ""
    return item("session.recognised", params, render("session.recognised", params, "en"))


def item_texts(stored: Mapping[str, Any] | str) -> dict[str, str]:
    """``{lang: text}`` of a stored :func:`item` (:func:`render_item`)."""
    return {lang: render_item(stored, lang) for lang in LANGUAGES}


__all__ = ["CATALOGUE", "item", "item_texts", "message_dict", "recognised_item", "render", "render_item"]
