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
        "pt": "Os ficheiros não puderam ser verificados em {seconds} s e a verificação foi interrompida; verifique "
              "se cada ficheiro é uma gravação desta sessão (um ficheiro feito para ser lento de ler é recusado), "
              "apague o errado e envie-o de novo."},
    "session.check_stopped": {
        "en": "The files could not be checked: the check stopped unexpectedly; delete the file you added last and "
              "upload it again, and if it happens again tell your ChakaMo administrator.",
        "es": "Los archivos no se pudieron comprobar: la comprobación se detuvo inesperadamente; borre el último "
              "archivo que añadió y súbalo de nuevo, y si vuelve a ocurrir avise a su administrador de ChakaMo.",
        "pt": "Os ficheiros não puderam ser verificados: a verificação parou inesperadamente; apague o último "
              "ficheiro que adicionou e envie-o de novo, e se voltar a acontecer avise o seu administrador do "
              "ChakaMo."},
    "session.check_busy": {
        "en": "The files are stored, but the server could not check them within {seconds} s because it is busy "
              "checking other files; open the session again in a moment and they are checked then.",
        "es": "Los archivos están guardados, pero el servidor no pudo comprobarlos en {seconds} s porque está "
              "ocupado comprobando otros archivos; abra la sesión de nuevo en un momento y se comprobarán entonces.",
        "pt": "Os ficheiros estão guardados, mas o servidor não pôde verificá-los em {seconds} s porque está "
              "ocupado a verificar outros ficheiros; abra a sessão de novo daqui a pouco e serão verificados então."},
    "session.no_files_yet": {
        "en": "No recordings yet; upload the session's files.",
        "es": "Todavía no hay grabaciones; suba los archivos de la sesión.",
        "pt": "Ainda não há gravações; envie os ficheiros da sessão."},
    "session.being_checked": {
        "en": "The session's files are being checked; reload in a moment.",
        "es": "Se están comprobando los archivos de la sesión; recargue en un momento.",
        "pt": "Os ficheiros da sessão estão a ser verificados; recarregue daqui a pouco."},
    "session.check_deferred": {
        "en": "The files are stored, but the server could not check them now; the check runs again when the "
              "session is opened or processed.",
        "es": "Los archivos están guardados, pero el servidor no pudo comprobarlos ahora; la comprobación se repite "
              "cuando se abra o se procese la sesión.",
        "pt": "Os ficheiros estão guardados, mas o servidor não pôde verificá-los agora; a verificação repete-se "
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
        "pt": "O corpo do pedido ocupa mais de {limit_kb} kB; os pedidos que não são envios de gravações "
              "levam corpos JSON pequenos: envie menos."},
    "request.multipart_malformed": {
        "en": "The multipart body is malformed; send the files with a standard form upload.",
        "es": "El cuerpo multipart está mal formado; envíe los archivos con un formulario estándar.",
        "pt": "O corpo multipart está malformado; envie os ficheiros com um formulário padrão."},
    "request.boundary_too_long": {
        "en": "The multipart boundary has {length} characters; a boundary has 1 to 70 (RFC 2046) — send the "
              "files with a standard form upload.",
        "es": "El delimitador multipart tiene {length} caracteres; un delimitador tiene de 1 a 70 (RFC 2046): "
              "envíe los archivos con un formulario estándar.",
        "pt": "O delimitador multipart tem {length} caracteres; um delimitador tem de 1 a 70 (RFC 2046): envie "
              "os ficheiros com um formulário padrão."},
    "request.file_name_controls": {
        "en": "File name {name} holds invisible characters that reorder how it is shown (Unicode bidirectional "
              "controls); rename the file (letters, digits, - _ .).",
        "es": "El nombre de archivo {name} contiene caracteres invisibles que cambian el orden en que se muestra "
              "(controles bidireccionales de Unicode); cambie el nombre del archivo (letras, dígitos, - _ .).",
        "pt": "O nome de ficheiro {name} contém caracteres invisíveis que mudam a ordem em que é mostrado "
              "(controlos bidirecionais do Unicode); renomeie o ficheiro (letras, dígitos, - _ .)."},
    "request.disk_full": {
        "en": "The server's disk is full, so the files could not be stored and none was recorded. Ask your "
              "ChakaMo administrator to free space, then upload them again.",
        "es": "El disco del servidor está lleno, así que los archivos no se pudieron guardar y no se registró "
              "ninguno. Pida a su administrador de ChakaMo que libere espacio y súbalos de nuevo.",
        "pt": "O disco do servidor está cheio, por isso os ficheiros não puderam ser guardados e nenhum foi "
              "registado. Peça ao seu administrador do ChakaMo que liberte espaço e envie-os de novo."},
    # ------------------------------------------------------------------------ uploads (app/web/api/recordings.py)
    "request.file_name_unusable": {
        "en": "File name {name} is not usable; rename the file (letters, digits, - _ .).",
        "es": "El nombre de archivo {name} no se puede usar; cambie el nombre del archivo (letras, dígitos, - _ .).",
        "pt": "O nome de ficheiro {name} não pode ser usado; renomeie o ficheiro (letras, dígitos, - _ .)."},
    "request.too_many_parts": {
        "en": "Too many parts in one upload; send at most {max_files} files and the fields segment and role.",
        "es": "Demasiadas partes en una subida; envíe como mucho {max_files} archivos y los campos segment y role.",
        "pt": "Demasiadas partes num envio; envie no máximo {max_files} ficheiros e os campos segment e role."},
    "request.part_header_too_long": {
        "en": "A multipart header is too long; send the files with a standard form upload.",
        "es": "Un encabezado multipart es demasiado largo; envíe los archivos con un formulario estándar.",
        "pt": "Um cabeçalho multipart é demasiado longo; envie os ficheiros com um formulário padrão."},
    "request.too_many_part_headers": {
        "en": "Too many headers in one multipart part; send a standard form upload.",
        "es": "Demasiados encabezados en una parte multipart; envíe un formulario estándar.",
        "pt": "Cabeçalhos demais numa parte multipart; envie um formulário padrão."},
    "request.field_not_accepted": {
        "en": "Form field {field} is not accepted; send the files in the field 'files' and, optionally, the "
              "fields 'segment' and 'role'.",
        "es": "El campo de formulario {field} no se acepta; envíe los archivos en el campo 'files' y, si quiere, "
              "los campos 'segment' y 'role'.",
        "pt": "O campo de formulário {field} não é aceite; envie os ficheiros no campo 'files' e, se quiser, os "
              "campos 'segment' e 'role'."},
    "request.field_twice": {
        "en": "Form field {field} sent twice; send it once per upload.",
        "es": "El campo de formulario {field} se envió dos veces; envíelo una vez por subida.",
        "pt": "O campo de formulário {field} foi enviado duas vezes; envie-o uma vez por envio."},
    "request.file_in_other_field": {
        "en": "File sent in form field {field}; send every file in the field 'files'.",
        "es": "Archivo enviado en el campo de formulario {field}; envíe cada archivo en el campo 'files'.",
        "pt": "Ficheiro enviado no campo de formulário {field}; envie cada ficheiro no campo 'files'."},
    "request.file_type": {
        "en": "{file}: files of type {suffix} are not accepted; upload {allowed} files (CSV of MetaBase, Xsens, "
              "Shimmer, phyphox or the generic layout, thesis Excel, zip of Sensor Logger or phyphox, session.json; "
              "an APDM .h5 file is read by the command line: chakamo process).",
        "es": "{file}: no se aceptan archivos del tipo {suffix}; suba archivos {allowed} (CSV de MetaBase, Xsens, "
              "Shimmer, phyphox o del formato genérico, Excel de la tesis, zip de Sensor Logger o phyphox, "
              "session.json; un archivo .h5 de APDM se lee con la línea de comandos: chakamo process).",
        "pt": "{file}: ficheiros do tipo {suffix} não são aceites; envie ficheiros {allowed} (CSV do MetaBase, Xsens, "
              "Shimmer, phyphox ou do formato genérico, Excel da tese, zip do Sensor Logger ou phyphox, "
              "session.json; um ficheiro .h5 da APDM é lido pela linha de comando: chakamo process)."},
    "request.json_not_manifest": {
        "en": "{file}: the only JSON file a session takes is its {manifest}; rename it.",
        "es": "{file}: el único archivo JSON que admite una sesión es su {manifest}; cámbiele el nombre.",
        "pt": "{file}: o único ficheiro JSON que uma sessão aceita é o seu {manifest}; renomeie-o."},
    "request.too_many_files": {
        "en": "More than {max_files} files in one upload; send at most {max_files} at a time.",
        "es": "Más de {max_files} archivos en una subida; envíe como mucho {max_files} cada vez.",
        "pt": "Mais de {max_files} ficheiros num envio; envie no máximo {max_files} de cada vez."},
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
        "pt": "O campo de formulário {field} é demasiado longo; aceita uma palavra curta."},
    "request.upload_too_large": {
        "en": "The upload is larger than {max_files} files of {limit_mb} MB; send fewer or smaller files.",
        "es": "La subida ocupa más que {max_files} archivos de {limit_mb} MB; envíe menos archivos o más pequeños.",
        "pt": "O envio é maior que {max_files} ficheiros de {limit_mb} MB; envie menos ficheiros ou menores."},
    "request.uploads_busy": {
        "en": "Too many uploads are in progress on this server; try again in a minute.",
        "es": "Hay demasiadas subidas en curso en este servidor; inténtelo de nuevo en un minuto.",
        "pt": "Há envios demais em andamento neste servidor; tente de novo em um minuto."},
    "request.not_multipart": {
        "en": "Send the files as multipart/form-data in the field 'files'.",
        "es": "Envíe los archivos como multipart/form-data en el campo 'files'.",
        "pt": "Envie os ficheiros como multipart/form-data no campo 'files'."},
    "request.no_file": {
        "en": "No file in the request; send the recordings in the multipart field 'files'.",
        "es": "No hay ningún archivo en la petición; envíe las grabaciones en el campo multipart 'files'.",
        "pt": "Não há nenhum ficheiro no pedido; envie as gravações no campo multipart 'files'."},
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
    "store.no_analysis": {
        "en": "No analysis {analysis_id} in session {session_id}; check the id.",
        "es": "No hay análisis {analysis_id} en la sesión {session_id}; compruebe el id.",
        "pt": "Não há análise {analysis_id} na sessão {session_id}; verifique o id."},
    "store.no_results": {
        "en": "Session {session_id} has no results yet; process it first (POST /api/v1/sessions/{session_id}/process).",
        "es": "La sesión {session_id} aún no tiene resultados; procésela primero (POST /api/v1/sessions/{session_id}/process).",
        "pt": "A sessão {session_id} ainda não tem resultados; processe-a primeiro (POST /api/v1/sessions/{session_id}/process)."},
    "store.no_artefact": {
        "en": "Analysis {analysis_id} has no {name}{in_lang}; process the session again to make it.",
        "es": "El análisis {analysis_id} no tiene {name}{in_lang}; procese la sesión de nuevo para generarlo.",
        "pt": "A análise {analysis_id} não tem {name}{in_lang}; processe a sessão de novo para gerá-lo."},
    "store.no_still": {
        "en": "The 3D recording of analysis {analysis_id} cannot be drawn as a still picture; open the 3D view, or "
              "process the session again to record it anew.",
        "es": "La grabación 3D del análisis {analysis_id} no se puede dibujar como imagen fija; abra la vista 3D o "
              "procese la sesión de nuevo para grabarla otra vez.",
        "pt": "A gravação 3D da análise {analysis_id} não pode ser desenhada como imagem fixa; abra a vista 3D ou "
              "processe a sessão de novo para a gravar outra vez."},
    "store.interpretation_empty": {
        "en": "The interpretation's {field} is empty; write it first.",
        "es": "El campo {field} de la interpretación está vacío; escríbalo primero.",
        "pt": "O campo {field} da interpretação está vazio; escreva-o primeiro."},
    "store.interpretation_too_long": {
        "en": "The interpretation's {field} is longer than {limit} characters; shorten it.",
        "es": "El campo {field} de la interpretación supera los {limit} caracteres; acórtelo.",
        "pt": "O campo {field} da interpretação excede {limit} caracteres; encurte-o."},
    "store.interpretation_signed": {
        "en": "The interpretation of analysis {analysis_id} was signed by {by} on {when} UTC and is locked; amend it with a reason instead.",
        "es": "La interpretación del análisis {analysis_id} la firmó {by} el {when} UTC y está bloqueada; enmiéndela indicando el motivo.",
        "pt": "A interpretação da análise {analysis_id} foi assinada por {by} em {when} UTC e está bloqueada; emende-a indicando o motivo."},
    "store.interpretation_not_signed": {
        "en": "The interpretation of analysis {analysis_id} is not signed yet; save the draft and sign it instead of amending.",
        "es": "La interpretación del análisis {analysis_id} aún no está firmada; guarde el borrador y fírmelo en lugar de enmendarlo.",
        "pt": "A interpretação da análise {analysis_id} ainda não está assinada; guarde o rascunho e assine-o em vez de o emendar."},
    "store.interpretation_needs_person": {
        "en": "Only a logged-in person can sign or amend an interpretation; an API token cannot. Log in and sign in the browser.",
        "es": "Solo una persona con sesión iniciada puede firmar o enmendar una interpretación; un token de la API no puede. Inicie sesión y firme en el navegador.",
        "pt": "Só uma pessoa com sessão iniciada pode assinar ou emendar uma interpretação; um token da API não pode. Inicie sessão e assine no navegador."},
    "store.interpretation_changed": {
        "en": "The interpretation of analysis {analysis_id} was changed by someone else meanwhile; reload it, read "
              "it and try again.",
        "es": "Otra persona ha cambiado la interpretación del análisis {analysis_id} mientras tanto; recárguela, "
              "léala e inténtelo de nuevo.",
        "pt": "Outra pessoa alterou a interpretação da análise {analysis_id} entretanto; recarregue-a, leia-a e "
              "tente de novo."},
    "store.interpretation_unchanged": {
        "en": "The amendment's text is the same as the signed text; change the text or leave it as it is.",
        "es": "El texto de la enmienda es igual al texto firmado; cambie el texto o déjelo como está.",
        "pt": "O texto da emenda é igual ao texto assinado; altere o texto ou deixe-o como está."},
    "store.exclusions_need_base": {
        "en": "Name the analysis the cycles were chosen on (based_on_analysis_id) with exclude_cycles.",
        "es": "Indique el análisis sobre el que se eligieron los ciclos (based_on_analysis_id) junto con exclude_cycles.",
        "pt": "Indique a análise sobre a qual os ciclos foram escolhidos (based_on_analysis_id) juntamente com exclude_cycles."},
    "store.exclusions_stale": {
        "en": "The cycles were chosen on analysis {analysis_id}, which is no longer the current analysis of session {session_id} (a newer one, or its files or details changed); open the current analysis and choose the cycles again.",
        "es": "Los ciclos se eligieron sobre el análisis {analysis_id}, que ya no es el análisis vigente de la sesión {session_id} (hay uno más reciente, o cambiaron sus ficheros o datos); abra el análisis vigente y elija los ciclos de nuevo.",
        "pt": "Os ciclos foram escolhidos na análise {analysis_id}, que já não é a análise em vigor da sessão {session_id} (há uma mais recente, ou mudaram os seus ficheiros ou dados); abra a análise em vigor e escolha os ciclos de novo."},
    "store.pair_itself": {
        "en": "Session {session_id} cannot be paired with itself; choose the patient's session of the other knee.",
        "es": "La sesión {session_id} no puede emparejarse consigo misma; elija la sesión del paciente de la otra rodilla.",
        "pt": "A sessão {session_id} não pode ser emparelhada consigo mesma; escolha a sessão do paciente do outro joelho."},
    "store.pair_other_patient": {
        "en": "Sessions {session_id} and {other_id} belong to different patients; pair two sessions of one patient.",
        "es": "Las sesiones {session_id} y {other_id} son de pacientes distintos; empareje dos sesiones del mismo paciente.",
        "pt": "As sessões {session_id} e {other_id} são de pacientes diferentes; emparelhe duas sessões do mesmo paciente."},
    "store.pair_both_knees": {
        "en": "Session {session_id} already holds both knees (four sensors); pair two sessions of one knee each.",
        "es": "La sesión {session_id} ya contiene ambas rodillas (cuatro sensores); empareje dos sesiones de una rodilla cada una.",
        "pt": "A sessão {session_id} já contém os dois joelhos (quatro sensores); emparelhe duas sessões de um joelho cada."},
    "store.pair_other_task": {
        "en": "Sessions {session_id} ({task}) and {other_id} ({other_task}) record different tasks; pair two sessions of the same task.",
        "es": "Las sesiones {session_id} ({task}) y {other_id} ({other_task}) registran tareas distintas; empareje dos sesiones de la misma tarea.",
        "pt": "As sessões {session_id} ({task}) e {other_id} ({other_task}) registam tarefas diferentes; emparelhe duas sessões da mesma tarefa."},
    "store.pair_knee_mismatch": {
        "en": "Session {session_id} would record the {knee} knee, but its file names say {files}; choose the knee the files record.",
        "es": "La sesión {session_id} registraría la rodilla {knee}, pero los nombres de sus ficheros dicen {files}; elija la rodilla que registran los ficheros.",
        "pt": "A sessão {session_id} registaria o joelho {knee}, mas os nomes dos seus ficheiros dizem {files}; escolha o joelho que os ficheiros registam."},
    "store.pair_other_date": {
        "en": "Paired although recorded on different dates (session {session_id}: {date}, session {other_id}: {other_date}); the limb symmetry index compares knees measured on different days.",
        "es": "Emparejadas aunque se registraron en fechas distintas (sesión {session_id}: {date}, sesión {other_id}: {other_date}); el índice de simetría compara rodillas medidas en días distintos.",
        "pt": "Emparelhadas embora registadas em datas diferentes (sessão {session_id}: {date}, sessão {other_id}: {other_date}); o índice de simetria compara joelhos medidos em dias diferentes."},
    "store.pair_bad_knee": {
        "en": "knee {knee!r} is unknown; use {allowed}.",
        "es": "la rodilla {knee!r} es desconocida; use {allowed}.",
        "pt": "o joelho {knee!r} é desconhecido; use {allowed}."},
    "store.superseded": {
        "en": "The results of session {session_id} were computed from recordings or details that have changed since (analysis {analysis_id}, superseded {when} UTC); process the session again{tail}.",
        "es": "Los resultados de la sesión {session_id} se calcularon con grabaciones o datos que han cambiado desde entonces (análisis {analysis_id}, reemplazado el {when} UTC); procese la sesión de nuevo{tail}.",
        "pt": "Os resultados da sessão {session_id} foram calculados com gravações ou dados que mudaram desde então (análise {analysis_id}, substituída em {when} UTC); processe a sessão de novo{tail}."},
    "store.unknown_segment": {
        "en": "segment {segment!r} is unknown; use {allowed}.",
        "es": "el segmento {segment!r} es desconocido; use {allowed}.",
        "pt": "o segmento {segment!r} é desconhecido; use {allowed}."},
    "store.unknown_role": {
        "en": "role {role!r} is unknown; use one of {allowed}.",
        "es": "el papel {role!r} es desconocido; use uno de {allowed}.",
        "pt": "o papel {role!r} é desconhecido; use um de {allowed}."},
    "store.sent_twice": {
        "en": "{names} sent twice in one upload; send each file once.",
        "es": "{names} enviado dos veces en una misma subida; envíe cada archivo una vez.",
        "pt": "{names} enviado duas vezes no mesmo envio; envie cada ficheiro uma vez."},
    "store.already_uploaded": {
        "en": "{names} already uploaded to this session; delete the earlier recording first to replace it.",
        "es": "{names} ya se subió a esta sesión; borre primero la grabación anterior para reemplazarla.",
        "pt": "{names} já foi enviado a esta sessão; apague primeiro a gravação anterior para substituí-la."},
    "store.too_many_files": {
        "en": "A session holds at most {limit} files ({stored} already stored); delete the ones not needed.",
        "es": "Una sesión admite como máximo {limit} archivos ({stored} ya guardados); borre los que no necesite.",
        "pt": "Uma sessão admite no máximo {limit} ficheiros ({stored} já guardados); apague os que não precisa."},
    "store.upload_raced": {
        "en": "{names}: another upload to this session stored a file of the same name at the same time; reload the session and check its files.",
        "es": "{names}: otra subida a esta sesión guardó un archivo con el mismo nombre al mismo tiempo; recargue la sesión y compruebe sus archivos.",
        "pt": "{names}: outro envio a esta sessão guardou um ficheiro com o mesmo nome ao mesmo tempo; recarregue a sessão e verifique os seus ficheiros."},
    "store.no_recording": {
        "en": "No recording {recording_id} in session {session_id}; check the ids.",
        "es": "No hay grabación {recording_id} en la sesión {session_id}; compruebe los ids.",
        "pt": "Não há gravação {recording_id} na sessão {session_id}; verifique os ids."},
    "store.no_session": {
        "en": "No session {session_id} in your clinic; check the id.",
        "es": "No hay sesión {session_id} en su clínica; compruebe el id.",
        "pt": "Não há sessão {session_id} na sua clínica; verifique o id."},
    "store.no_job": {
        "en": "No job {job_id} in your clinic; check the id.",
        "es": "No hay trabajo {job_id} en su clínica; compruebe el id.",
        "pt": "Não há tarefa {job_id} na sua clínica; verifique o id."},
    "store.clinic_unknown": {
        "en": "no clinic named {name!r} (known: {known}); create it with `chakamo clinics create`",
        "es": "no hay ninguna clínica llamada {name!r} (conocidas: {known}); créela con `chakamo clinics create`",
        "pt": "não há nenhuma clínica chamada {name!r} (conhecidas: {known}); crie-a com `chakamo clinics create`"},
    # the hand-over of ``chakamo reprocess``'s jobs (app/jobs/reprocess.py)
    "jobs.reprocess_none": {"en": "no job queued", "es": "ningún trabajo en cola", "pt": "nenhuma tarefa em fila"},
    "jobs.reprocess_celery": {
        "en": "{n} jobs queued and handed to the Celery workers",
        "es": "{n} trabajos en cola y entregados a los workers de Celery",
        "pt": "{n} tarefas em fila e entregues aos workers do Celery"},
    "jobs.reprocess_celery_partly": {
        "en": "{n} jobs queued, {sent} handed to the broker; the others are sent when it answers (the server's and "
              "the workers' sweepers)",
        "es": "{n} trabajos en cola, {sent} entregados al broker; los demás se envían cuando responda (los barridos "
              "del servidor y de los workers)",
        "pt": "{n} tarefas em fila, {sent} entregues ao broker; as outras são enviadas quando ele responder (as "
              "varreduras do servidor e dos workers)"},
    "jobs.reprocess_embedded": {
        "en": "{n} jobs queued; the running `chakamo serve` takes them within seconds (or at its next start)",
        "es": "{n} trabajos en cola; el `chakamo serve` en marcha los toma en segundos (o en su próximo arranque)",
        "pt": "{n} tarefas em fila; o `chakamo serve` em execução recolhe-as em segundos (ou no seu próximo "
              "arranque)"},
    "store.busy": {
        "en": "Session {session_id} is being processed (job {job_id}); {what} when that job has finished.",
        "es": "La sesión {session_id} se está procesando (trabajo {job_id}); {what} cuando ese trabajo haya terminado.",
        "pt": "A sessão {session_id} está a ser processada (tarefa {job_id}); {what} quando essa tarefa tiver terminado."},
    # what the clinician may do once the job has finished ({what} of store.busy)
    "store.then.process": {"en": "process it again", "es": "procésela de nuevo", "pt": "processe-a de novo"},
    "store.then.upload": {"en": "upload the files", "es": "suba los archivos", "pt": "envie os ficheiros"},
    "store.then.correct": {"en": "correct it", "es": "corríjala", "pt": "corrija-a"},
    "store.then.pair": {"en": "pair it", "es": "emparéjela", "pt": "emparelhe-a"},
    "store.then.unpair": {"en": "undo the pairing", "es": "deshaga el emparejamiento", "pt": "desfaça o emparelhamento"},
    "store.then.delete": {"en": "delete it", "es": "bórrela", "pt": "apague-a"},
    "store.then.delete_files": {"en": "delete files", "es": "borre archivos", "pt": "apague ficheiros"},
    "store.then.move_cuts": {"en": "move the cuts", "es": "mueva los cortes", "pt": "mova os cortes"},
    "store.then.correct_patient": {"en": "correct the patient", "es": "corrija el paciente",
                                   "pt": "corrija o paciente"},
    "store.then.delete_patient": {"en": "delete the patient", "es": "borre el paciente", "pt": "apague o paciente"},
    # {tail} of store.superseded when the superseded analysis can be asked for by id
    "store.superseded_tail": {
        "en": ", or ask for analysis_id={analysis_id} to see the superseded report",
        "es": ", o pida analysis_id={analysis_id} para ver el informe reemplazado",
        "pt": ", ou peça analysis_id={analysis_id} para ver o relatório substituído"},
    "store.changed_meanwhile": {
        "en": "{kind} {row_id} was changed by someone else meanwhile (it is now version {version}, you sent {expected}); reload it and try again.",
        "es": "{kind} {row_id} fue cambiado por otra persona mientras tanto (ahora es la versión {version}, usted envió {expected}); recárguelo e inténtelo de nuevo.",
        "pt": "{kind} {row_id} foi alterado por outra pessoa entretanto (agora é a versão {version}, enviou {expected}); recarregue-o e tente de novo."},
    "store.not_correctable": {
        "en": "{fields} cannot be corrected; correct {allowed}.",
        "es": "{fields} no se puede corregir; corrija {allowed}.",
        "pt": "{fields} não pode ser corrigido; corrija {allowed}."},
    "store.empty_value": {
        "en": "{field} cannot be empty; give a value.",
        "es": "{field} no puede estar vacío; indique un valor.",
        "pt": "{field} não pode estar vazio; indique um valor."},
    "store.step_out_of_range": {
        "en": "step_height_m {value} is out of range; give the step's height in metres (e.g. 0.17).",
        "es": "step_height_m {value} está fuera de rango; indique la altura del escalón en metros (p. ej. 0,17).",
        "pt": "step_height_m {value} está fora do intervalo; indique a altura do degrau em metros (p. ex. 0,17)."},
    "store.unknown_task": {
        "en": "task {task!r} is unknown; use one of {allowed}.",
        "es": "la tarea {task!r} es desconocida; use una de {allowed}.",
        "pt": "a tarefa {task!r} é desconhecida; use uma de {allowed}."},
    "store.unknown_event": {
        "en": "unknown or no event {events}; use {allowed}",
        "es": "evento desconocido o ninguno {events}; use {allowed}",
        "pt": "evento desconhecido ou nenhum {events}; use {allowed}"},
    "store.no_webhook": {
        "en": "No webhook {webhook_id} in your clinic; check the id.",
        "es": "No hay webhook {webhook_id} en su clínica; compruebe el id.",
        "pt": "Não há webhook {webhook_id} na sua clínica; verifique o id."},
    "store.out_of_range": {
        "en": "{field} {value} is out of range; give a value between {low} and {high}.",
        "es": "{field} {value} está fuera de rango; indique un valor entre {low} y {high}.",
        "pt": "{field} {value} está fora do intervalo; indique um valor entre {low} e {high}."},
    "store.unknown_value": {
        "en": "{field} {value!r} is unknown; use one of {allowed}.",
        "es": "{field} {value!r} es desconocido; use uno de {allowed}.",
        "pt": "{field} {value!r} é desconhecido; use um de {allowed}."},
    "store.no_patient": {
        "en": "No patient {patient_id} in your clinic; check the id.",
        "es": "No hay paciente {patient_id} en su clínica; compruebe el id.",
        "pt": "Não há paciente {patient_id} na sua clínica; verifique o id."},
    "store.patient_exists": {
        "en": "Patient {external_id!r} already exists in your clinic{with_id}; open that patient instead.",
        "es": "El paciente {external_id!r} ya existe en su clínica{with_id}; abra ese paciente.",
        "pt": "O paciente {external_id!r} já existe na sua clínica{with_id}; abra esse paciente."},
    "store.patient_id_taken": {
        "en": "Patient {external_id!r} already exists in your clinic{with_id}; choose another identifier.",
        "es": "El paciente {external_id!r} ya existe en su clínica{with_id}; elija otro identificador.",
        "pt": "O paciente {external_id!r} já existe na sua clínica{with_id}; escolha outro identificador."},
    "store.not_patients_session": {
        "en": "Session {session_id} is not one of patient {patient_id}'s; compare two sessions of one patient.",
        "es": "La sesión {session_id} no es del paciente {patient_id}; compare dos sesiones de un mismo paciente.",
        "pt": "A sessão {session_id} não é do paciente {patient_id}; compare duas sessões de um mesmo paciente."},
    "store.email_taken": {
        "en": "The email {email} already has an account; use another email.",
        "es": "El correo {email} ya tiene una cuenta; use otro correo.",
        "pt": "O e-mail {email} já tem uma conta; use outro e-mail."},
    "store.key_reused": {
        "en": "Idempotency-Key {key!r} was used for another request; send a new key for a new request.",
        "es": "La Idempotency-Key {key!r} se usó para otra petición; envíe una clave nueva para una petición nueva.",
        "pt": "A Idempotency-Key {key!r} foi usada noutro pedido; envie uma chave nova para um pedido novo."},
    "store.key_in_flight": {
        "en": "A request with Idempotency-Key {key!r} is still running; retry in a few seconds.",
        "es": "Una petición con la Idempotency-Key {key!r} aún está en curso; reintente en unos segundos.",
        "pt": "Um pedido com a Idempotency-Key {key!r} ainda está em curso; tente de novo em alguns segundos."},
    "store.not_ready": {
        "en": "The session's recordings are not ready to process: {reason}",
        "es": "Las grabaciones de la sesión no están listas para procesar: {reason}",
        "pt": "As gravações da sessão não estão prontas para processar: {reason}"},
    "request.if_match_required": {
        "en": "This deletion erases the record and everything under it for good; send 'If-Match' with the version "
              "you saw (the ETag of its GET) or '*' to confirm.",
        "es": "Esta eliminación borra el registro y todo lo que contiene para siempre; envíe 'If-Match' con la "
              "versión que vio (la ETag de su GET) o '*' para confirmar.",
        "pt": "Esta eliminação apaga o registo e tudo o que ele contém para sempre; envie 'If-Match' com a versão "
              "que viu (a ETag do seu GET) ou '*' para confirmar."},
    "request.if_match_unreadable": {
        "en": "If-Match {value!r} is not a version; send the ETag of the GET, e.g. \"3\".",
        "es": "If-Match {value!r} no es una versión; envíe la ETag del GET, p. ej. \"3\".",
        "pt": "If-Match {value!r} não é uma versão; envie a ETag do GET, p. ex. \"3\"."},
    "request.fhir_not_exportable": {
        "en": "Session {session_id} cannot be exported to FHIR ({reason}); correct the record and try again, or "
              "tell your ChakaMo administrator.",
        "es": "La sesión {session_id} no se puede exportar a FHIR ({reason}); corrija el registro y vuelva a "
              "intentarlo, o avise a su administrador de ChakaMo.",
        "pt": "A sessão {session_id} não pode ser exportada para FHIR ({reason}); corrija o registo e tente de "
              "novo, ou avise o seu administrador do ChakaMo."},
    # the FHIR export's refusals (app.web.fhir.FhirExportError), quoted by request.fhir_not_exportable
    "fhir.not_a_dict": {
        "en": "{name} must be a dict with the keys {keys}, got {got}",
        "es": "{name} debe ser un dict con las claves {keys}, se recibió {got}",
        "pt": "{name} deve ser um dict com as chaves {keys}, recebeu-se {got}"},
    "fhir.missing_keys": {
        "en": "{name} is missing the key(s) {missing}; pass all of {keys} (None where unknown)",
        "es": "a {name} le faltan la(s) clave(s) {missing}; pase todas las de {keys} (None si se desconoce)",
        "pt": "a {name} faltam a(s) chave(s) {missing}; passe todas as de {keys} (None se desconhecida)"},
    "fhir.bad_lang": {
        "en": "lang must be one of {choices}, got {value}",
        "es": "lang debe ser uno de {choices}, se recibió {value}",
        "pt": "lang deve ser um de {choices}, recebeu-se {value}"},
    "fhir.not_pdf": {
        "en": "pdf must be the bytes of the PDF report (starting with %PDF-); render the report first",
        "es": "pdf debe ser los bytes del informe PDF (empezando por %PDF-); genere antes el informe",
        "pt": "pdf deve ser os bytes do relatório PDF (começando por %PDF-); gere antes o relatório"},
    "fhir.bad_base_url": {
        "en": "base_url must be an absolute http(s) URL such as http://host/api/v1, got {value}",
        "es": "base_url debe ser una URL http(s) absoluta como http://host/api/v1, se recibió {value}",
        "pt": "base_url deve ser um URL http(s) absoluto como http://host/api/v1, recebeu-se {value}"},
    "fhir.bad_patient_mode": {
        "en": "patient_mode must be one of {choices}, got {value}",
        "es": "patient_mode debe ser uno de {choices}, se recibió {value}",
        "pt": "patient_mode deve ser um de {choices}, recebeu-se {value}"},
    "fhir.bad_patient_reference": {
        "en": "patient fhir_reference {value} is not a FHIR reference such as Patient/123",
        "es": "la fhir_reference del paciente {value} no es una referencia FHIR como Patient/123",
        "pt": "a fhir_reference do paciente {value} não é uma referência FHIR como Patient/123"},
    "fhir.no_patient_identifier": {
        "en": "the patient can be referred to by identifier only with a record number and "
              "CHAKAMO_PATIENT_IDENTIFIER_SYSTEM set (or, with CHAKAMO_FHIR_PATIENT=reference, give the patient its "
              "fhir_reference)",
        "es": "solo se puede referir al paciente por identificador con un número de historia y "
              "CHAKAMO_PATIENT_IDENTIFIER_SYSTEM definido (o, con CHAKAMO_FHIR_PATIENT=reference, dé al paciente su "
              "fhir_reference)",
        "pt": "só se pode referir o paciente por identificador com um número de processo e "
              "CHAKAMO_PATIENT_IDENTIFIER_SYSTEM definido (ou, com CHAKAMO_FHIR_PATIENT=reference, dê ao paciente a "
              "sua fhir_reference)"},
    "fhir.bad_session_reference": {
        "en": "session {key} {value} is not a FHIR reference such as {example}/123",
        "es": "{key} de la sesión {value} no es una referencia FHIR como {example}/123",
        "pt": "{key} da sessão {value} não é uma referência FHIR como {example}/123"},
    "fhir.results_missing": {
        "en": "results is missing {path}; pass the session's results.json as written by chakamo process (reprocess "
              "the session if it predates this key)",
        "es": "a results le falta {path}; pase el results.json de la sesión tal como lo escribe chakamo process "
              "(procese de nuevo la sesión si es anterior a esta clave)",
        "pt": "a results falta {path}; passe o results.json da sessão tal como o escreve chakamo process (processe "
              "de novo a sessão se for anterior a esta chave)"},
    "fhir.results_not_a_dict": {
        "en": "results must be the session's results.json as a dict, got {got}",
        "es": "results debe ser el results.json de la sesión como dict, se recibió {got}",
        "pt": "results deve ser o results.json da sessão como dict, recebeu-se {got}"},
    "fhir.results_side": {
        "en": "results['side'] must be 'right' or 'left', got {value}",
        "es": "results['side'] debe ser 'right' o 'left', se recibió {value}",
        "pt": "results['side'] deve ser 'right' ou 'left', recebeu-se {value}"},
    "fhir.results_count": {
        "en": "results['cycles']['{key}'] must be a count (int >= 0), got {value}",
        "es": "results['cycles']['{key}'] debe ser un recuento (int >= 0), se recibió {value}",
        "pt": "results['cycles']['{key}'] deve ser uma contagem (int >= 0), recebeu-se {value}"},
    "fhir.results_warnings": {
        "en": "results['quality']['warnings'] must be a list of {{'code', 'message'}} objects",
        "es": "results['quality']['warnings'] debe ser una lista de objetos {{'code', 'message'}}",
        "pt": "results['quality']['warnings'] deve ser uma lista de objetos {{'code', 'message'}}"},
    "fhir.results_number": {
        "en": "results {where} must be a number or null, got {value}",
        "es": "results {where} debe ser un número o null, se recibió {value}",
        "pt": "results {where} deve ser um número ou null, recebeu-se {value}"},
    "fhir.bad_id": {
        "en": "the {what} {value} cannot be a FHIR id (1-64 of A-Z a-z 0-9 - .)",
        "es": "{what} {value} no puede ser un id FHIR (de 1 a 64 de A-Z a-z 0-9 - .)",
        "pt": "{what} {value} não pode ser um id FHIR (de 1 a 64 de A-Z a-z 0-9 - .)"},
    "fhir.bad_date": {
        "en": "the {what} {value} is not an ISO date (YYYY-MM-DD) or date-time",
        "es": "{what} {value} no es una fecha ISO (AAAA-MM-DD) ni una fecha y hora",
        "pt": "{what} {value} não é uma data ISO (AAAA-MM-DD) nem uma data e hora"},
    "fhir.date_required": {
        "en": "the {what} is required: give an ISO date (YYYY-MM-DD), a date or a datetime, got {value}",
        "es": "{what} es obligatoria: dé una fecha ISO (AAAA-MM-DD), un date o un datetime, se recibió {value}",
        "pt": "{what} é obrigatória: dê uma data ISO (AAAA-MM-DD), um date ou um datetime, recebeu-se {value}"},
    "fhir.bad_issued": {
        "en": "issued must be a timezone-aware datetime, got {value}",
        "es": "issued debe ser un datetime con zona horaria, se recibió {value}",
        "pt": "issued deve ser um datetime com fuso horário, recebeu-se {value}"},
    "fhir.bad_sex": {
        "en": "patient sex {value} is not one of male, female, other, unknown (or m, f); fix the patient record",
        "es": "el sexo del paciente {value} no es uno de male, female, other, unknown (o m, f); corrija la ficha del "
              "paciente",
        "pt": "o sexo do paciente {value} não é um de male, female, other, unknown (ou m, f); corrija a ficha do "
              "paciente"},
    "fhir.not_r4": {
        "en": "{resource} is not valid FHIR R4 (4.0.1, fhirclient): {detail}",
        "es": "{resource} no es FHIR R4 válido (4.0.1, fhirclient): {detail}",
        "pt": "{resource} não é FHIR R4 válido (4.0.1, fhirclient): {detail}"},
    "fhir.not_r4b": {
        "en": "{resource} fails FHIR validation (fhir.resources R4B): {detail}",
        "es": "{resource} no supera la validación FHIR (fhir.resources R4B): {detail}",
        "pt": "{resource} não passa a validação FHIR (fhir.resources R4B): {detail}"},
    "fhir.field.session_id": {"en": "session id", "es": "el id de la sesión", "pt": "o id da sessão"},
    "fhir.field.session_date": {"en": "session date (or created_at when the date is None)",
                                "es": "la fecha de la sesión (o created_at si la fecha es None)",
                                "pt": "a data da sessão (ou created_at se a data for None)"},
    "fhir.field.birth_date": {"en": "patient birth_date", "es": "la fecha de nacimiento del paciente",
                              "pt": "a data de nascimento do paciente"},
    "request.events_other_clinic": {
        "en": "This event stream was opened for another clinic than the one you are now logged in to; open it "
              "again.",
        "es": "Este flujo de eventos se abrió para otra clínica que aquella en la que ha iniciado sesión ahora; "
              "ábralo de nuevo.",
        "pt": "Este fluxo de eventos foi aberto para outra clínica que aquela em que iniciou sessão agora; "
              "abra-o de novo."},
    "store.up_to_date": {
        "en": "analysis {analysis_id} (pipeline {version})",
        "es": "análisis {analysis_id} (pipeline {version})",
        "pt": "análise {analysis_id} (pipeline {version})"},
    "request.invalid": {
        "en": "{fields}: invalid or missing value. Correct the request and send it again.",
        "es": "{fields}: valor no válido o ausente. Corrija la petición y envíela de nuevo.",
        "pt": "{fields}: valor inválido ou ausente. Corrija o pedido e envie-o de novo."},
    "store.unknown_scope": {
        "en": "unknown scope {scopes}; use resource:read or resource:write, e.g. {examples} (all: {all})",
        "es": "ámbito desconocido {scopes}; use recurso:read o recurso:write, p. ej. {examples} (todos: {all})",
        "pt": "âmbito desconhecido {scopes}; use recurso:read ou recurso:write, p. ex. {examples} (todos: {all})"},
    "store.no_scope": {
        "en": "no scope given; name at least one, or leave --scope out for every scope of the role",
        "es": "no se indicó ningún ámbito; nombre al menos uno, u omita --scope para todos los ámbitos del rol",
        "pt": "nenhum âmbito indicado; nomeie pelo menos um, ou omita --scope para todos os âmbitos do papel"},
    "store.unknown_token_role": {
        "en": "unknown role {role!r}; use one of {allowed}",
        "es": "rol desconocido {role!r}; use uno de {allowed}",
        "pt": "papel desconhecido {role!r}; use um de {allowed}"},
    "store.expiry_out_of_range": {
        "en": "a lifetime of {days} days is out of range; give more than 0 and at most {limit} days",
        "es": "una validez de {days} días está fuera de rango; indique más de 0 y como mucho {limit} días",
        "pt": "uma validade de {days} dias está fora do intervalo; indique mais de 0 e no máximo {limit} dias"},
    "store.no_token": {
        "en": "no API token with id {token_id}; see the ids on the Administration page (API tokens) or with "
              "`chakamo tokens list --clinic NAME`",
        "es": "no hay token de API con id {token_id}; vea los ids en la página de Administración (tokens de API) o "
              "con `chakamo tokens list --clinic NOMBRE`",
        "pt": "não há token de API com id {token_id}; veja os ids na página de Administração (tokens de API) ou "
              "com `chakamo tokens list --clinic NOME`"},
    "store.token_dead": {
        "en": "token {token_id} is revoked or expired; create a new one on the Administration page (API tokens) or "
              "with `chakamo tokens create`",
        "es": "el token {token_id} está revocado o caducado; cree uno nuevo en la página de Administración (tokens "
              "de API) o con `chakamo tokens create`",
        "pt": "o token {token_id} está revogado ou expirado; crie um novo na página de Administração (tokens de "
              "API) ou com `chakamo tokens create`"},
    "store.grace_out_of_range": {
        "en": "--grace-hours {hours} is out of range; give 0 to {limit} hours",
        "es": "--grace-hours {hours} está fuera de rango; indique de 0 a {limit} horas",
        "pt": "--grace-hours {hours} está fora do intervalo; indique de 0 a {limit} horas"},
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
